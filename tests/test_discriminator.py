"""Tests for the SAIL discriminator (modules/discriminator.py) and its loss (objectives/discriminator.py)."""

from __future__ import annotations

import argparse
import math

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn

from torchrl_sail import (
    Discriminator,
    DiscriminatorLoss,
    DiscriminatorNet,
    RunningObsNorm,
)


def _np_stats(x: np.ndarray, eps: float = 1e-2, min_var: float = 1e-2):
    """Authors' MPI RunningMeanStd: prior sum=0, sumsq=eps, count=eps; var floored."""
    x = x.reshape(-1, x.shape[-1]).astype(np.float64)
    s = x.sum(0)
    sq = eps + (x**2).sum(0)
    c = eps + x.shape[0]
    mean = s / c
    std = np.sqrt(np.maximum(sq / c - mean**2, min_var))
    return mean, std


def _linear_disc(weight, bias=0.0, *, obs_dim=3, act_dim=1, normalize=False):
    """A discriminator whose logit is the affine map ``weight @ [obs, act] + bias``."""
    disc = Discriminator(obs_dim, act_dim, num_cells=(), normalize_observations=normalize)
    with torch.no_grad():
        disc.net.mlp[0].weight.copy_(torch.tensor([weight], dtype=torch.float32))
        disc.net.mlp[0].bias.fill_(bias)
    return disc


def _tagged(obs, act, tag):
    obs = torch.as_tensor(obs, dtype=torch.float32)
    return TensorDict(
        observation=obs,
        action=torch.as_tensor(act, dtype=torch.float32),
        is_teacher=torch.as_tensor(tag, dtype=torch.bool),
        batch_size=obs.shape[:-1],
    )


class TestRunningObsNorm:
    def test_prior(self):
        norm = RunningObsNorm(3)
        assert norm.sum.dtype == norm.sumsq.dtype == norm.count.dtype == torch.float64
        torch.testing.assert_close(norm.mean, torch.zeros(3, dtype=torch.float64))
        # sumsq/count = 1 and mean = 0 before any update
        torch.testing.assert_close(norm.std, torch.ones(3, dtype=torch.float64))
        assert set(norm.state_dict()) == {"sum", "sumsq", "count"}

    def test_hand_computed(self):
        norm = RunningObsNorm(2)
        norm.update(torch.tensor([[1.0, 5.0], [3.0, 5.0]]))
        # count = 2.01, mean = (4, 10) / 2.01
        # var0 = 10.01/2.01 - (4/2.01)^2, var1 = 50.01/2.01 - (10/2.01)^2
        c = 2.01
        mean = [4 / c, 10 / c]
        std = [math.sqrt(10.01 / c - mean[0] ** 2), math.sqrt(50.01 / c - mean[1] ** 2)]
        assert norm.mean.tolist() == pytest.approx(mean, abs=1e-12)
        assert norm.std.tolist() == pytest.approx(std, abs=1e-12)
        assert norm.std.tolist() == pytest.approx([1.009852, 0.358796], abs=1e-6)

    def test_matches_numpy_over_several_batches(self):
        norm = RunningObsNorm(3)
        a = torch.randn(7, 3) * torch.tensor([1.0, 5.0, 0.01]) + torch.tensor([2.0, -1.0, 1.0])
        b = torch.randn(2, 5, 3) * torch.tensor([1.0, 1.0, 0.01]) + 1.0  # any leading dims
        norm.update(a)
        norm.update(b)
        allx = np.concatenate([a.numpy(), b.reshape(-1, 3).numpy()])
        mean, std = _np_stats(allx)
        np.testing.assert_allclose(norm.mean.numpy(), mean, rtol=1e-12)
        np.testing.assert_allclose(norm.std.numpy(), std, rtol=1e-10)
        assert norm.count.item() == pytest.approx(17.01)
        # third feature is ~1 +- 0.01: its variance (prior row at 0 included) < 1e-2,
        # so its std is floored at 0.1
        assert (norm.sumsq / norm.count - norm.mean**2)[2] < 1e-2
        assert norm.std[2].item() == pytest.approx(0.1)
        x = torch.randn(4, 3) * 100  # no clipping of the normalised values
        out = norm(x)
        assert out.dtype == torch.float32
        expected = (x.double().numpy() - mean) / std
        np.testing.assert_allclose(out.numpy(), expected, rtol=1e-5, atol=1e-3)
        assert out.abs().max() > 100

    def test_std_floor(self):
        norm = RunningObsNorm(1)
        norm.update(torch.full((100, 1), 3.0))
        # var = 900.01/100.01 - (300/100.01)^2 ~ 1e-3 < 1e-2 -> std = 0.1
        raw_var = 900.01 / 100.01 - (300 / 100.01) ** 2
        assert 0 < raw_var < 1e-2
        assert norm.std.item() == pytest.approx(0.1, abs=1e-15)
        # mean and std are cast to x's dtype (float32) first, as the authors do
        assert norm(torch.tensor([[3.0]])).item() == pytest.approx((3.0 - 300 / 100.01) / 0.1, abs=1e-5)
        assert norm(torch.tensor([[4.0]])).item() == pytest.approx((4.0 - 300 / 100.01) / 0.1, rel=1e-6)

    def test_forward_does_not_update(self):
        norm = RunningObsNorm(2)
        before = {k: v.clone() for k, v in norm.state_dict().items()}
        norm(torch.randn(5, 2))
        for k, v in norm.state_dict().items():
            assert torch.equal(v, before[k])

    def test_bad_arguments(self):
        with pytest.raises(ValueError, match="epsilon=0.0"):
            RunningObsNorm(3, epsilon=0.0)
        with pytest.raises(ValueError, match="min_var=-1"):
            RunningObsNorm(3, min_var=-1)


class TestDiscriminatorNet:
    def test_architecture_and_glorot_init(self):
        net = DiscriminatorNet(17, 6)
        linears = [m for m in net.mlp if isinstance(m, nn.Linear)]
        assert [(m.in_features, m.out_features) for m in linears] == [
            (23, 256),
            (256, 256),
            (256, 1),
        ]
        assert [type(m) for m in net.mlp if not isinstance(m, nn.Linear)] == [nn.Tanh] * 2
        for m in linears:
            assert torch.count_nonzero(m.bias) == 0
            bound = math.sqrt(6.0 / (m.in_features + m.out_features))
            assert m.weight.abs().max() <= bound
            # uniform(-b, b) has std b/sqrt(3); PyTorch's default would be much smaller
            if m.weight.numel() > 1000:
                assert m.weight.std().item() == pytest.approx(bound / math.sqrt(3), rel=0.05)

    def test_forward_by_hand(self):
        net = DiscriminatorNet(3, 2, num_cells=(4,))
        net.obs_norm.update(torch.randn(20, 3) * 3 + 1)
        obs, act = torch.randn(5, 3), torch.rand(5, 2)
        mean, std = net.obs_norm.mean.float(), net.obs_norm.std.float()
        x = torch.cat([(obs - mean) / std, act], -1)
        w1, b1 = net.mlp[0].weight, net.mlp[0].bias
        w2, b2 = net.mlp[2].weight, net.mlp[2].bias
        expected = torch.tanh(x @ w1.T + b1) @ w2.T + b2
        torch.testing.assert_close(net.features(obs, act), x)
        torch.testing.assert_close(net(obs, act), expected)
        assert net(obs, act).shape == (5, 1)

    def test_forward_is_pure(self):
        net = DiscriminatorNet(3, 1, num_cells=(8,))
        before = {k: v.clone() for k, v in net.state_dict().items()}
        with torch.no_grad():
            net(torch.randn(6, 3) + 10, torch.rand(6, 1))
        net.train()
        net(torch.randn(6, 3) + 10, torch.rand(6, 1))
        for k, v in net.state_dict().items():
            assert torch.equal(v, before[k]), k

    def test_no_normalisation(self):
        net = DiscriminatorNet(3, 1, num_cells=(8,), normalize_observations=False)
        assert net.obs_norm is None
        obs, act = torch.randn(4, 3) * 7, torch.rand(4, 1)
        torch.testing.assert_close(net.features(obs, act), torch.cat([obs, act], -1))

    def test_spectral_norm(self):
        torch.manual_seed(0)
        net = DiscriminatorNet(5, 2, num_cells=(16, 16), spectral_norm=True)
        obs, act = torch.randn(64, 5), torch.rand(64, 2)
        linears = [m for m in net.mlp.modules() if isinstance(m, nn.Linear)]
        assert len(linears) == 3

        def singular_values(weights):
            return [torch.linalg.matrix_norm(w.detach(), 2).item() for w in weights]

        # a plain forward, in training mode too, is pure: the singular vectors do not move
        vectors = {k: v.clone() for k, v in net.state_dict().items() if k.endswith(("_u", "_v"))}
        assert len(vectors) == 6
        net.train()
        net(obs, act)
        assert all(torch.equal(net.state_dict()[k], v) for k, v in vectors.items())
        with net.spectral_norm_iteration():
            for _ in range(30):  # one power iteration per forward in the context
                net(obs, act)
        assert not torch.equal(net.state_dict()[next(iter(vectors))], next(iter(vectors.values())))
        # the effective weights' largest singular value is 1; the raw ones' is not
        assert singular_values(layer.weight for layer in linears) == pytest.approx([1.0] * 3, abs=1e-3)
        assert min(singular_values(layer.parametrizations.weight.original for layer in linears)) > 1.1
        # saved and loaded with the weights
        before = net(obs, act)
        copy = DiscriminatorNet(5, 2, num_cells=(16, 16), spectral_norm=True)
        copy.load_state_dict(net.state_dict())
        assert torch.equal(copy(obs, act), before)
        # re-initialised: the same parameters, the normalisation estimated afresh on the new weights
        params = list(net.parameters())
        net.reset_parameters()
        assert all(a is b for a, b in zip(params, net.parameters(), strict=True))
        assert not torch.equal(net(obs, act), before)
        assert singular_values(layer.weight for layer in linears) == pytest.approx([1.0] * 3, abs=0.05)


class TestDiscriminator:
    def test_tensordict_face(self):
        disc = Discriminator(3, 2, num_cells=(8, 8))
        assert disc.in_keys == ["observation", "action"]
        assert disc.out_keys == ["d_logit"]
        assert isinstance(disc.net, DiscriminatorNet)
        td = TensorDict(
            observation=torch.randn(2, 5, 3),
            action=torch.rand(2, 5, 2),
            batch_size=[2, 5],
        )
        disc.net.obs_norm.update(torch.randn(50, 3) * 2 + 1)
        out = disc(td)
        assert out["d_logit"].shape == (2, 5, 1)
        # the architecture by hand: normalise s, concat (s, a), tanh MLP, linear head
        norm = disc.net.obs_norm
        obs = ((td["observation"].double() - norm.mean) / norm.std).float()
        h = torch.cat([obs, td["action"]], -1)
        linears = [m for m in disc.net.mlp.modules() if isinstance(m, nn.Linear)]
        assert len(linears) == 3
        for layer in linears[:-1]:
            h = torch.tanh(h @ layer.weight.T + layer.bias)
        expected = h @ linears[-1].weight.T + linears[-1].bias
        torch.testing.assert_close(out["d_logit"], expected.detach())

    def test_custom_keys(self):
        disc = Discriminator(
            3,
            2,
            num_cells=(),
            normalize_observations=False,
            in_keys=[("a", "obs"), "act"],
            out_key="logit",
        )
        with torch.no_grad():
            disc.net.mlp[0].weight.copy_(torch.tensor([[1.0, 2.0, 3.0, 4.0, 5.0]]))
            disc.net.mlp[0].bias.fill_(0.5)
        td = TensorDict(
            {
                ("a", "obs"): torch.tensor([[1.0, 0.0, 0.0], [0.0, 1.0, -1.0]]),
                "act": torch.tensor([[0.5, -0.5], [1.0, 0.0]]),
            },
            [2],
        )
        # 1 + (2 - 2.5) + 0.5 = 1.0 and (2 - 3) + 4 + 0.5 = 3.5
        assert disc(td)["logit"][:, 0].tolist() == [1.0, 3.5]
        assert "d_logit" not in td.keys()

    def test_float64(self):
        # a float64 discriminator takes float64 observations; float32 actions are cast
        td = TensorDict(
            observation=torch.randn(4, 3, dtype=torch.float64),
            action=torch.rand(4, 2),
            batch_size=[4],
        )
        disc64 = Discriminator(3, 2, num_cells=(8,)).double()
        assert disc64.net.dtype == torch.float64
        assert disc64(td.clone())["d_logit"].dtype == torch.float64


class TestDiscriminatorLoss:
    def test_hand_computed_linear(self):
        # logit = 3*obs0 + 4*obs1 (no normalisation): |grad| = 5 everywhere -> GP = 16
        disc = _linear_disc([3.0, 4.0, 0.0, 0.0])
        obs = [[1.0, 0, 0], [0.5, -1, 0], [-2, 0.25, 9], [0, 0, 0], [-1, 0, 0]]
        tag = [True, False, True, False, True]
        loss_fn = DiscriminatorLoss(disc)
        out = loss_fn(_tagged(obs, torch.zeros(5, 1), tag))
        logits = [3 * o[0] + 4 * o[1] for o in obs]  # [3, -2.5, -5, 0, -3]
        lt = [z for z, t in zip(logits, tag, strict=True) if t]
        la = [z for z, t in zip(logits, tag, strict=True) if not t]
        softplus = lambda z: math.log1p(math.exp(z))  # noqa: E731
        sig = lambda z: 1 / (1 + math.exp(-z))  # noqa: E731
        bce = sum(softplus(-z) for z in lt) / 3 + sum(softplus(z) for z in la) / 2
        ent = sum(-sig(z) * math.log(sig(z)) - (1 - sig(z)) * math.log(1 - sig(z)) for z in logits) / 5
        assert out["loss_discriminator"].item() == pytest.approx(bce, rel=1e-6)
        assert out["entropy"].item() == pytest.approx(ent, rel=1e-5)
        assert out["loss_entropy"].item() == pytest.approx(-0.01 * ent, rel=1e-5)
        assert out["grad_penalty"].item() == pytest.approx(16.0, rel=1e-6)
        assert out["loss_gradient_penalty"].item() == pytest.approx(160.0, rel=1e-6)
        # teacher logits [3, -5, -3] -> 1/3 right; agent logits [-2.5, 0]: 0 is not < 0.5
        assert out["accuracy_teacher"].item() == pytest.approx(1 / 3)
        assert out["accuracy_agent"].item() == pytest.approx(1 / 2)
        assert out["d_teacher"].item() == pytest.approx(sum(map(sig, lt)) / 3, rel=1e-6)
        assert out["d_agent"].item() == pytest.approx(sum(map(sig, la)) / 2, rel=1e-6)
        assert out["reward_teacher"].item() == pytest.approx(sum(map(softplus, lt)) / 3, rel=1e-6)
        assert out["reward_agent"].item() == pytest.approx(sum(map(softplus, la)) / 2, rel=1e-6)
        for k in loss_fn.out_keys:
            assert out[k].shape == ()
        for k in ("accuracy_teacher", "entropy", "grad_penalty", "reward_agent"):
            assert not out[k].requires_grad

    def test_spread_and_logit_diagnostics_by_hand(self):
        disc = _linear_disc([3.0, 4.0, 0.0, 0.0])
        obs = [[1.0, 0, 0], [0.5, -1, 0], [-2, 0.25, 9], [0, 0, 0], [-1, 0, 0]]
        out = DiscriminatorLoss(disc)(_tagged(obs, torch.zeros(5, 1), [True, False, True, False, True]))
        softplus = lambda z: math.log1p(math.exp(z))  # noqa: E731
        rt, ra = [softplus(z) for z in (3.0, -5.0, -3.0)], [softplus(z) for z in (-2.5, 0.0)]
        std = lambda xs: math.sqrt(sum((x - sum(xs) / len(xs)) ** 2 for x in xs) / len(xs))  # noqa: E731
        assert out["logit_teacher"].item() == pytest.approx(-5 / 3, rel=1e-6)
        assert out["logit_agent"].item() == pytest.approx(-1.25, rel=1e-6)
        assert out["reward_teacher_std"].item() == pytest.approx(std(rt), rel=1e-5)
        assert out["reward_agent_std"].item() == pytest.approx(std(ra), rel=1e-5)
        assert out["logit_teacher_std"].item() == pytest.approx(std([3.0, -5.0, -3.0]), rel=1e-5)
        assert out["logit_agent_std"].item() == pytest.approx(1.25, rel=1e-6)  # logits -2.5 and 0

    def test_training_step_advances_spectral_norm_once(self):
        torch.manual_seed(0)
        disc = Discriminator(3, 1, num_cells=(8,), spectral_norm=True)
        loss_fn = DiscriminatorLoss(disc)
        td = _tagged(torch.randn(6, 3), torch.zeros(6, 1), [1, 0, 1, 0, 1, 0])

        def vectors():
            return [v.clone() for k, v in disc.state_dict().items() if k.endswith("_v")]

        with torch.no_grad():  # as after optimiser steps: the vectors are no longer converged
            for layer in (m for m in disc.net.mlp.modules() if isinstance(m, nn.Linear)):
                layer.parametrizations.weight.original.add_(torch.randn_like(layer.parametrizations.weight.original))
        start = vectors()
        loss_fn.eval()
        loss_fn(td)  # evaluating the loss leaves D's normalisation as it is
        assert all(torch.equal(a, b) for a, b in zip(start, vectors(), strict=True))
        loss_fn.train()
        loss_fn(td)
        after_one = vectors()
        assert all(not torch.equal(a, b) for a, b in zip(start, after_one, strict=True))
        # one iteration per step, whatever the step computes besides (penalty, diagnostics): from the
        # same v (the iteration computes u from v, then v from u), one head call gives the same vectors
        v_keys = [k for k in disc.state_dict() if k.endswith("_v")]
        disc.load_state_dict({**disc.state_dict(), **dict(zip(v_keys, start, strict=True))})
        with disc.net.spectral_norm_iteration():
            disc.net.head(disc.net.features(td["observation"], td["action"]))
        assert all(torch.equal(a, b) for a, b in zip(after_one, vectors(), strict=True))

    def test_label_smoothing_by_hand(self):
        # teacher targets 1 - 0.2: BCE(z, 0.8) = softplus(-z) + 0.2 * z; agent targets stay 0
        disc = _linear_disc([3.0, 4.0, 0.0, 0.0])
        obs = [[1.0, 0, 0], [0.5, -1, 0], [-2, 0.25, 9], [0, 0, 0], [-1, 0, 0]]
        tag = [True, False, True, False, True]
        loss_fn = DiscriminatorLoss(disc, label_smoothing=0.2)
        out = loss_fn(_tagged(obs, torch.zeros(5, 1), tag))
        softplus = lambda z: math.log1p(math.exp(z))  # noqa: E731
        bce = sum(softplus(-z) + 0.2 * z for z in (3.0, -5.0, -3.0)) / 3 + sum(softplus(z) for z in (-2.5, 0.0)) / 2
        assert out["loss_discriminator"].item() == pytest.approx(bce, rel=1e-6)
        # the smoothed optimum of a teacher row is a finite logit, log(0.8 / 0.2)
        z = torch.tensor([math.log(4.0)], requires_grad=True)
        torch.nn.functional.binary_cross_entropy_with_logits(z, torch.tensor([0.8])).backward()
        assert abs(z.grad.item()) < 1e-6
        loss_fn.label_smoothing = 0.0  # schedulable: back to the plain BCE
        plain = DiscriminatorLoss(disc)(_tagged(obs, torch.zeros(5, 1), tag))["loss_discriminator"]
        assert loss_fn(_tagged(obs, torch.zeros(5, 1), tag))["loss_discriminator"].item() == pytest.approx(plain.item())
        with pytest.raises(ValueError, match="label_smoothing must be in \\[0, 0.5\\)"):
            DiscriminatorLoss(disc, label_smoothing=0.5)

    def test_instance_noise_by_hand(self):
        # logit = 3*f0 + 4*f1 of the noisy features f + sigma * n, n the loss's randn_like draw
        disc = _linear_disc([3.0, 4.0, 0.0, 0.0])
        obs = torch.tensor([[1.0, 0, 0], [0.5, -1, 0], [-2, 0.25, 9], [0, 0, 0]])
        tag = [True, False, True, False]
        loss_fn = DiscriminatorLoss(disc, instance_noise=0.5)
        torch.manual_seed(7)
        out = loss_fn(_tagged(obs, torch.zeros(4, 1), tag))
        torch.manual_seed(7)
        noise = torch.randn(4, 4)
        noisy = torch.cat([obs, torch.zeros(4, 1)], -1) + 0.5 * noise
        z = (3 * noisy[:, 0] + 4 * noisy[:, 1]).tolist()
        softplus = lambda x: math.log1p(math.exp(x))  # noqa: E731
        bce = (softplus(-z[0]) + softplus(-z[2])) / 2 + (softplus(z[1]) + softplus(z[3])) / 2
        assert out["loss_discriminator"].item() == pytest.approx(bce, rel=1e-5)
        # the diagnostics (all but the entropy term) and the penalty use the clean features:
        # logits [3, -2.5, -5, 0], |grad| = 5
        assert out["logit_teacher"].item() == pytest.approx(-1.0, rel=1e-6)
        assert out["accuracy_agent"].item() == pytest.approx(0.5)
        assert out["grad_penalty"].item() == pytest.approx(16.0, rel=1e-6)
        # no noise outside training mode
        loss_fn.eval()
        clean = loss_fn(_tagged(obs, torch.zeros(4, 1), tag))["loss_discriminator"].item()
        expected = (softplus(-3.0) + softplus(5.0)) / 2 + (softplus(-2.5) + softplus(0.0)) / 2
        assert clean == pytest.approx(expected, rel=1e-6)
        with pytest.raises(ValueError, match="instance_noise must be a finite number >= 0"):
            DiscriminatorLoss(disc, instance_noise=-0.1)

    def test_unit_gradient_gives_zero_penalty(self):
        disc = _linear_disc([0.6, 0.0, 0.0, 0.8])  # |w| = 1
        out = DiscriminatorLoss(disc)(_tagged(torch.randn(6, 3), torch.rand(6, 1), [1, 0, 1, 0, 1, 0]))
        assert out["grad_penalty"].item() == pytest.approx(0.0, abs=1e-12)

    def test_against_reference(self):
        torch.manual_seed(1)
        disc = Discriminator(3, 2, num_cells=(5,))
        # move the biases away from Glorot's zeros so every term is exercised
        with torch.no_grad():
            for p in disc.parameters():
                p.add_(0.3 * torch.randn_like(p))
        loss_fn = DiscriminatorLoss(disc, entropy_coef=0.05, gp_coef=3.0)
        obs = torch.randn(10, 3) * 2 + 1
        act = torch.rand(10, 2) * 2 - 1
        tag = torch.tensor([1, 0, 0, 1, 1, 0, 1, 1, 0, 1], dtype=torch.bool)  # 6 teacher, 4 agent
        torch.manual_seed(123)
        out = loss_fn(_tagged(obs, act, tag))
        total = sum(v for k, v in out.items() if k.startswith("loss_"))
        total.backward()
        grads = [p.grad.clone() for p in disc.parameters()]

        # reference: same normaliser statistics (updated with all 10 rows), plain torch ops
        mean, std = _np_stats(obs.numpy())
        np.testing.assert_allclose(disc.net.obs_norm.mean.numpy(), mean, rtol=1e-12)
        w1, b1 = disc.net.mlp[0].weight, disc.net.mlp[0].bias
        w2, b2 = disc.net.mlp[2].weight, disc.net.mlp[2].bias
        x = torch.cat(
            [
                (obs - torch.tensor(mean, dtype=torch.float32)) / torch.tensor(std, dtype=torch.float32),
                act,
            ],
            -1,
        )

        def head(z):
            return torch.tanh(z @ w1.T + b1) @ w2.T + b2

        z = head(x)
        p = torch.sigmoid(z)
        bce = -torch.log(p[tag]).mean() - torch.log(1 - p[~tag]).mean()
        ent = (-p * torch.log(p) - (1 - p) * torch.log(1 - p)).mean()
        torch.manual_seed(123)
        eps = torch.rand(4, 1)  # one weight per (teacher_i, agent_i) pair
        x_hat = eps * x[~tag][:4] + (1 - eps) * x[tag][:4]
        # analytic input gradient of a 1-hidden-layer tanh net
        h = torch.tanh(x_hat @ w1.T + b1)
        g = ((1 - h**2) * w2) @ w1
        gp = ((g.norm(dim=-1) - 1) ** 2).mean()
        torch.testing.assert_close(out["loss_discriminator"], bce.detach())
        torch.testing.assert_close(out["entropy"], ent.detach())
        torch.testing.assert_close(out["loss_entropy"], -0.05 * ent.detach())
        torch.testing.assert_close(out["grad_penalty"], gp.detach())
        torch.testing.assert_close(out["loss_gradient_penalty"], 3.0 * gp.detach())

        disc.zero_grad()
        (bce - 0.05 * ent + 3.0 * gp).backward()
        for got, ref in zip(grads, [p.grad for p in disc.parameters()], strict=True):
            torch.testing.assert_close(got, ref)
        # the penalty really reaches the weights (double backward)
        assert all(torch.count_nonzero(gr) > 0 for gr in grads)

    def test_interpolation_resampled_each_call(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        loss_fn = DiscriminatorLoss(disc, update_obs_norm=False)
        td = _tagged(torch.randn(8, 3) * 3, torch.rand(8, 1), torch.arange(8) < 4)
        gp1 = loss_fn(td)["grad_penalty"]
        gp2 = loss_fn(td)["grad_penalty"]
        assert gp1 != gp2
        torch.manual_seed(5)
        gp3 = loss_fn(td)["grad_penalty"]
        torch.manual_seed(5)
        assert loss_fn(td)["grad_penalty"] == gp3

    def test_obs_norm_update_only_in_training_with_all_rows(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        loss_fn = DiscriminatorLoss(disc)
        td = _tagged(torch.randn(6, 3) + 2, torch.rand(6, 1), [1, 1, 0, 0, 0, 1])
        loss_fn.eval()
        loss_fn(td)
        assert disc.net.obs_norm.count.item() == pytest.approx(0.01)
        loss_fn.train()
        loss_fn(td)
        norm = disc.net.obs_norm
        assert norm.count.item() == pytest.approx(6.01)
        torch.testing.assert_close(norm.sum, td["observation"].double().sum(0))
        torch.testing.assert_close(norm.sumsq, 0.01 + td["observation"].double().square().sum(0))
        DiscriminatorLoss(disc, update_obs_norm=False)(td)
        assert norm.count.item() == pytest.approx(6.01)

    def test_input_not_modified_and_no_grad_eval(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        loss_fn = DiscriminatorLoss(disc, update_obs_norm=False)
        td = _tagged(torch.randn(6, 3), torch.rand(6, 1), [1, 0, 1, 0, 1, 0])
        before = td.clone()
        torch.manual_seed(3)
        out = loss_fn(td)
        assert set(td.keys()) == set(before.keys())
        assert (td == before).all()
        torch.manual_seed(3)
        with torch.no_grad():
            out_ng = loss_fn(td)
        for k in loss_fn.out_keys:
            torch.testing.assert_close(out_ng[k], out[k].detach())
        assert not out_ng["loss_gradient_penalty"].requires_grad

    def test_time_batch(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        loss_fn = DiscriminatorLoss(disc, update_obs_norm=False)
        tag = torch.zeros(2, 4, dtype=torch.bool)
        tag[0] = True
        obs, act = torch.randn(2, 4, 3), torch.rand(2, 4, 1)
        out = loss_fn(_tagged(obs, act, tag))
        flat = loss_fn.eval()(_tagged(obs.reshape(8, 3), act.reshape(8, 1), tag.reshape(8)))
        torch.testing.assert_close(out["loss_discriminator"], flat["loss_discriminator"])

    def test_schedulable_coefficients(self):
        disc = _linear_disc([3.0, 4.0, 0.0, 0.0])
        loss_fn = DiscriminatorLoss(disc)
        td = _tagged(torch.randn(4, 3), torch.zeros(4, 1), [1, 0, 1, 0])
        assert isinstance(loss_fn.entropy_coef, torch.Tensor)
        assert {"entropy_coef", "gp_coef", "label_smoothing", "instance_noise"} <= set(loss_fn.state_dict())
        loss_fn.entropy_coef = 0.5
        loss_fn.gp_coef = 2.0
        out = loss_fn(td)
        assert out["loss_entropy"].item() == pytest.approx(-0.5 * out["entropy"].item())
        assert out["loss_gradient_penalty"].item() == pytest.approx(32.0, rel=1e-6)
        assert loss_fn.gp_coef.dtype == torch.float32
        # a state dict saved before label_smoothing and instance_noise existed loads, strictly
        older = {k: v for k, v in loss_fn.state_dict().items() if k not in ("label_smoothing", "instance_noise")}
        fresh = DiscriminatorLoss(_linear_disc([3.0, 4.0, 0.0, 0.0]), label_smoothing=0.1)
        fresh.load_state_dict(older)
        assert fresh.gp_coef.item() == 2.0 and fresh.label_smoothing.item() == pytest.approx(0.1)

    def test_keys(self):
        disc = Discriminator(3, 1, num_cells=(8,), in_keys=["obs", "act"])
        loss_fn = DiscriminatorLoss(disc)
        assert loss_fn.in_keys == ["obs", "act", "is_teacher"]
        loss_fn.set_keys(is_teacher=("source", "teacher"))
        assert loss_fn.in_keys == ["obs", "act", ("source", "teacher")]
        td = TensorDict(
            {
                "obs": torch.randn(4, 3),
                "act": torch.rand(4, 1),
                ("source", "teacher"): torch.tensor([True, False] * 2),
            },
            [4],
        )
        assert loss_fn(td)["loss_discriminator"].shape == ()
        with pytest.raises(ValueError, match="not an accepted tensordict key"):
            loss_fn.set_keys(teacher="x")
        loss_fn.set_keys(is_teacher=None)
        assert loss_fn.tensor_keys.is_teacher == "is_teacher"
        # a plain TensorDictModule around a DiscriminatorNet works too
        plain = TensorDictModule(DiscriminatorNet(3, 1, num_cells=(4,)), in_keys=["o", "a"], out_keys=["l"])
        loss_fn = DiscriminatorLoss(plain)
        assert loss_fn.in_keys == ["o", "a", "is_teacher"]
        out = loss_fn(o=torch.randn(4, 3), a=torch.rand(4, 1), is_teacher=td["source", "teacher"])
        assert out[0].shape == ()

    def test_one_class_batch_raises(self):
        # a batch without teacher or without agent rows would give a NaN loss
        disc = Discriminator(3, 1, num_cells=(8,))
        loss_fn = DiscriminatorLoss(disc)
        td = _tagged(torch.randn(4, 3), torch.rand(4, 1), [1, 0, 1, 0])
        with pytest.raises(ValueError, match=r"4 rows with 'is_teacher'=True and 0"):
            loss_fn(td.set("is_teacher", torch.ones(4, dtype=torch.bool)))
        with pytest.raises(ValueError, match=r"0 rows with 'is_teacher'=True"):
            loss_fn(td.set("is_teacher", torch.zeros(4, dtype=torch.bool)))
        # nothing was learnt from the rejected batches
        assert disc.net.obs_norm.count.item() == pytest.approx(0.01)

    def test_reset_parameters_recursive(self):
        disc = Discriminator(3, 1, num_cells=(64,))
        loss_fn = DiscriminatorLoss(disc)
        with torch.no_grad():
            for p in disc.parameters():
                p.fill_(0.5)
        disc.net.obs_norm.update(torch.ones(4, 3))
        loss_fn.reset_parameters_recursive()
        w = disc.net.mlp[0].weight
        bound = math.sqrt(6.0 / (4 + 64))
        assert w.abs().max() <= bound and w.abs().max() > 0.8 * bound
        assert all(torch.count_nonzero(m.bias) == 0 for m in (disc.net.mlp[0], disc.net.mlp[2]))
        assert disc.net.obs_norm.count.item() == pytest.approx(4.01)

    def test_separates_toy_distributions(self):
        # authors' 256-256 tanh net; ~1 s on one core
        disc = Discriminator(3, 1)
        loss_fn = DiscriminatorLoss(disc)
        optim = torch.optim.Adam(disc.parameters(), lr=1e-3)
        tag = torch.arange(256) < 128

        def batch():
            teacher = torch.randn(128, 4) * 0.5 + 2
            agent = torch.randn(128, 4) * 0.5 - 2
            x = torch.cat([teacher, agent])
            return _tagged(x[:, :3], x[:, 3:], tag)

        for _ in range(200):
            out = loss_fn(batch())
            loss = out["loss_discriminator"] + out["loss_entropy"] + out["loss_gradient_penalty"]
            optim.zero_grad()
            loss.backward()
            optim.step()
        loss_fn.eval()
        out = loss_fn(batch())
        assert out["accuracy_teacher"] > 0.95
        assert out["accuracy_agent"] > 0.95
        assert out["reward_teacher"] > out["reward_agent"]
        assert out["d_teacher"] > 0.5 > out["d_agent"]


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)


def test_orthogonal_init_gives_orthonormal_weights_and_xavier_stays_the_default():
    from torchrl_sail import DiscriminatorNet

    torch.manual_seed(0)
    orthogonal = DiscriminatorNet(5, 3, num_cells=(16, 4), init="orthogonal")
    for layer in orthogonal._linears():
        w = layer.weight.detach()
        gram = w @ w.T if w.shape[0] <= w.shape[1] else w.T @ w  # the shorter side is orthonormal
        torch.testing.assert_close(gram, torch.eye(min(w.shape)), atol=1e-5, rtol=0)
        assert torch.count_nonzero(layer.bias) == 0
    default = DiscriminatorNet(5, 3, num_cells=(16, 4))
    assert default.init == "xavier"
    for layer in default._linears():
        fan_out, fan_in = layer.weight.shape
        assert layer.weight.abs().max() <= math.sqrt(6 / (fan_in + fan_out))  # Glorot-uniform's bound
    with pytest.raises(ValueError, match=r"init='kaiming': must be one of \['orthogonal', 'torch', 'xavier'\]"):
        DiscriminatorNet(5, 3, init="kaiming")


def test_torch_init_is_nn_linears_own():
    from torchrl_sail import DiscriminatorNet

    net = DiscriminatorNet(5, 3, num_cells=(16, 4), init="torch")
    for layer in net._linears():
        bound = 1 / math.sqrt(layer.weight.shape[1])  # nn.Linear: Kaiming-uniform(a=sqrt(5)) and uniform biases
        assert layer.weight.abs().max() <= bound and layer.bias.abs().max() <= bound
        assert torch.count_nonzero(layer.bias) == layer.bias.numel()  # not the zero biases of the other inits
