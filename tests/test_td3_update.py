"""Tests for TD3Update (objectives/td3_update.py): the fused step equals the loss's own step.

Both implementations run on copies of the same loss, with the same seed, batches and
optimizers; losses, gradients and parameters must agree to float rounding."""

from __future__ import annotations

import argparse
import copy
import warnings

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torch.overrides import TorchFunctionMode
from torchrl.data import Bounded
from torchrl.modules import MLP, TanhModule, ValueOperator
from torchrl.objectives import SoftUpdate, TD3Loss
from torchrl.objectives.value import TD0Estimator

import torchrl_sail.objectives.td3_update as td3_update
from torchrl_sail import SAILLoss, TD3Update

OBS, ACT, B = 5, 2, 32
DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])


def make_loss(spec, *, cls=SAILLoss, device="cpu", activation=nn.ReLU, num_cells=(16, 12), layer_norm=False, **kwargs):
    """``layer_norm``: ``nn.LayerNorm`` after every hidden Linear of both nets (RLPD's critic), with
    eps 1e-3 (not torch's default) and perturbed affine parameters, so that a norm run without them
    cannot pass; a dict of ``nn.LayerNorm`` keyword arguments (``elementwise_affine``, ``bias``)
    builds the norms with them."""
    options = layer_norm if isinstance(layer_norm, dict) else {}
    norm = (
        {
            "norm_class": nn.LayerNorm,
            "norm_kwargs": [{"normalized_shape": cells, "eps": 1e-3, **options} for cells in num_cells],
        }
        if layer_norm is not False
        else {}
    )
    actor = TensorDictSequential(
        TensorDictModule(
            MLP(in_features=OBS, out_features=ACT, num_cells=list(num_cells), activation_class=activation, **norm),
            ["observation"],
            ["param"],
        ),
        TanhModule(["param"], ["action"], spec=spec),
    )
    critic = ValueOperator(
        MLP(in_features=OBS + ACT, out_features=1, num_cells=list(num_cells), activation_class=activation, **norm),
        in_keys=["action", "observation"],
    )
    g = torch.Generator().manual_seed(3)
    with torch.no_grad():
        for module in (*actor.modules(), *critic.modules()):
            for param in module.parameters(recurse=False) if isinstance(module, nn.LayerNorm) else ():
                param.add_(0.5 * torch.randn(param.shape, generator=g))
    kwargs.setdefault("loss_function", "l2")
    loss = cls(actor, critic, action_spec=spec, **kwargs)
    loss.make_value_estimator(gamma=0.9)
    return loss.to(device)  # the estimator's gamma too


def make_update(loss, implementation, *, fused_adam=False, capturable=False, **kwargs):
    # Targets start as copies of the online nets; perturb them so that mixing up online and
    # target parameters cannot go unnoticed. SoftUpdate copies online -> target when built.
    updater = SoftUpdate(loss, tau=0.05)
    g = torch.Generator().manual_seed(7)
    with torch.no_grad():
        for name, buf in loss.named_buffers():
            if name.startswith("target_") and name.endswith(("weight", "bias")):
                buf.add_(0.3 * torch.randn(buf.shape, generator=g).to(buf.device))
    return TD3Update(
        loss,
        critic_optimizer=torch.optim.Adam(
            loss.qvalue_network_params.flatten_keys().values(), lr=1e-2, fused=fused_adam, capturable=capturable
        ),
        actor_optimizer=torch.optim.Adam(
            loss.actor_network_params.flatten_keys().values(), lr=1e-2, fused=fused_adam, capturable=capturable
        ),
        target_updater=updater,
        implementation=implementation,
        **kwargs,
    )


def make_batch(spec, *, seed, device="cpu", n_teacher=B // 4, steps_key=None, nstep=False):
    """Random transitions; ``steps_key``: a step count 1..10 there; ``nstep``: an n-step view under "next_n"."""
    g = torch.Generator().manual_seed(seed)
    terminated = torch.rand(B, 1, generator=g) < 0.2
    truncated = torch.rand(B, 1, generator=g) < 0.1
    batch = TensorDict(
        {
            "observation": torch.randn(B, OBS, generator=g),
            "action": spec.low + (spec.high - spec.low) * torch.rand(B, ACT, generator=g),
            "is_teacher": torch.arange(B) < n_teacher,
            ("next", "observation"): torch.randn(B, OBS, generator=g),
            ("next", "reward"): torch.randn(B, 1, generator=g),
            ("next", "terminated"): terminated,
            ("next", "truncated"): truncated,
            ("next", "done"): terminated | truncated,
        },
        [B],
    )
    if steps_key is not None:
        batch[steps_key] = torch.randint(1, 11, (B, 1), generator=g)
    if nstep:
        terminated_n = terminated | (torch.rand(B, 1, generator=g) < 0.3)  # the window reaches further
        truncated_n = ~terminated_n & (torch.rand(B, 1, generator=g) < 0.1)
        batch["next_n"] = TensorDict(
            {
                "observation": torch.randn(B, OBS, generator=g),
                "reward": 3 * torch.randn(B, 1, generator=g),
                "terminated": terminated_n,
                "truncated": truncated_n,
                "done": terminated_n | truncated_n,
                "steps_to_next_obs": torch.randint(1, 11, (B, 1), generator=g),
            },
            [B],
        )
    return batch.to(device)


def q_value(loss, params, obs, action):
    """One critic's Q(s, a) with ``params`` (a row per batch row)."""
    with params.to_module(loss.qvalue_network):
        td = TensorDict({"observation": obs, "action": action}, [obs.shape[0]])
        return loss.qvalue_network(td)["state_action_value"].squeeze(-1)


@torch.no_grad()
def squared_one_step_errors(loss, batch):
    """``(Q_i(s, a) - r - 0.9 (1 - term) min_j Q'_j(s', pi'(s')))^2`` of both critics (``[2, B]``),
    by hand; the loss's ``policy_noise`` must be 0."""
    with loss.target_actor_network_params.to_module(loss.actor_network):
        next_action = loss.actor_network(batch["next"].clone())["action"]
    next_obs = batch["next", "observation"]
    next_q = torch.stack([q_value(loss, loss.target_qvalue_network_params[i], next_obs, next_action) for i in (0, 1)])
    target = (
        batch["next", "reward"].squeeze(-1) + 0.9 * (~batch["next", "terminated"]).squeeze(-1) * next_q.min(0).values
    )
    q = torch.stack(
        [q_value(loss, loss.qvalue_network_params[i], batch["observation"], batch["action"]) for i in (0, 1)]
    )
    return (q - target) ** 2


def recording(update):
    """Records the gradients each optimizer steps with."""
    grads = []
    for opt in (update.critic_optimizer, update.actor_optimizer):
        params = [p for group in opt.param_groups for p in group["params"]]
        opt.register_step_pre_hook(
            lambda *_, params=params: grads.append([None if p.grad is None else p.grad.clone() for p in params])
        )
    return grads


def run_both(spec, steps=6, *, device="cpu", loss_kwargs=None, batch_kwargs=None, set_keys=None, **kwargs):
    """Runs the same seeded steps with both implementations; returns (metrics, grads, state) per impl."""
    torch.manual_seed(0)
    base = make_loss(spec, device=device, **(loss_kwargs or {}))
    if set_keys:
        base.set_keys(**set_keys)
    out = {}
    for implementation in ("loss", "fused"):
        loss = copy.deepcopy(base)
        update = make_update(loss, implementation, **kwargs)
        grads = recording(update)
        torch.manual_seed(1)  # the policy-smoothing noise
        metrics = [
            update(make_batch(spec, seed=i, device=device, **(batch_kwargs or {})), update_actor=i % 2 == 0)
            for i in range(steps)
        ]
        out[implementation] = (metrics, grads, loss.state_dict())
    return out


def assert_same(out, atol=1e-5):
    (m_ref, g_ref, s_ref), (m_fast, g_fast, s_fast) = out["loss"], out["fused"]
    for a, b in zip(m_ref, m_fast, strict=True):
        assert a.keys() == b.keys()
        for key in a:
            torch.testing.assert_close(b[key], a[key], atol=atol, rtol=1e-5, msg=key)
    assert len(g_ref) == len(g_fast) > 0
    for step_ref, step_fast in zip(g_ref, g_fast, strict=True):
        for a, b in zip(step_ref, step_fast, strict=True):
            assert (a is None) == (b is None)  # the TanhModule bounds are in the actor's params, never a grad
            if a is not None:
                torch.testing.assert_close(b, a, atol=atol, rtol=1e-4)
    assert s_ref.keys() == s_fast.keys()
    for key in s_ref:
        torch.testing.assert_close(s_fast[key], s_ref[key], atol=atol, rtol=1e-4, msg=key)


UNIT = Bounded(-1.0, 1.0, (ACT,))


class TestTD3Update:
    @pytest.mark.parametrize("device", DEVICES)
    def test_fused_equals_loss_default(self, device):
        # SAIL's default: mixing="batch", TD3's terminal handling (bootstrap unless terminated)
        assert_same(run_both(UNIT, device=device))

    def test_fused_equals_loss_authors_terminal(self):
        # the example's truncation_is_terminal: done stops bootstrapping
        assert_same(run_both(UNIT, set_keys={"terminated": "done"}))

    @pytest.mark.parametrize("n_teacher", [0, B // 4, B])
    def test_fused_equals_loss_weights(self, n_teacher):
        # Algorithm 1's weighted form, including the one-group edge cases
        assert_same(
            run_both(UNIT, loss_kwargs={"mixing": "weights", "alpha": 0.3}, batch_kwargs={"n_teacher": n_teacher})
        )

    def test_fused_equals_loss_smooth_l1(self):
        assert_same(run_both(UNIT, loss_kwargs={"loss_function": "smooth_l1"}))

    @pytest.mark.parametrize("device", DEVICES)
    @pytest.mark.parametrize("layer_norm", [True, {"bias": False}, {"elementwise_affine": False}])
    def test_fused_equals_loss_layer_norm(self, device, layer_norm):
        # LayerNorm after each hidden layer of both nets (network.critic_layer_norm puts it in the critic)
        assert_same(run_both(UNIT, device=device, loss_kwargs={"layer_norm": layer_norm}))

    def test_fused_stacked_layer_norm_critics_equal_each_critic_module(self):
        # the stacked critics (batch-major where a norm is) against each critic's own nn.LayerNorm module
        loss = make_loss(UNIT, layer_norm=True)
        update = make_update(loss, "fused")
        batch = make_batch(UNIT, seed=0)
        x = torch.cat([batch["action"], batch["observation"]], -1)
        stacked = td3_update._run(update._critic, x).squeeze(-1)
        assert stacked.shape == (2, B)
        for i in (0, 1):
            torch.testing.assert_close(
                stacked[i], q_value(loss, loss.qvalue_network_params[i], batch["observation"], batch["action"])
            )

    def test_fused_equals_loss_bounds_and_activation(self):
        # TanhModule's affine map onto non-symmetric bounds, and a non-ReLU activation
        spec = Bounded(torch.tensor([-2.0, 0.0]), torch.tensor([0.5, 3.0]), (ACT,))
        assert_same(run_both(spec, loss_kwargs={"activation": nn.Tanh, "num_cells": (16,)}))

    @pytest.mark.parametrize("implementation", ["loss", "fused"])
    def test_td_error_is_the_squared_one_step_error_max_over_the_critics(self, implementation):
        # DDPGfD's priorities start from it; policy_noise=0 makes the target a plain forward pass
        torch.manual_seed(0)
        loss = make_loss(UNIT, policy_noise=0.0)
        update = make_update(loss, implementation, td_error=True)
        batch = make_batch(UNIT, seed=3)
        expected = squared_one_step_errors(loss, batch).max(0).values
        update(batch, update_actor=False)
        torch.testing.assert_close(batch["td_error"], expected, rtol=1e-5, atol=1e-6)

    @pytest.mark.parametrize("implementation", ["loss", "fused"])
    @pytest.mark.parametrize("normalization", ["count", "sum"])
    def test_importance_weights_reduce_as_per_or_as_torchrl(self, implementation, normalization):
        # SAILLoss(weight_normalization): PER's mean_i(w_i l_i) ("count") or TorchRL's
        # sum_i w_i l_i / sum_i w_i ("sum"), l_i the row's loss: both critics' squared errors; -Q_1(s, pi(s))
        torch.manual_seed(0)
        loss = make_loss(UNIT, policy_noise=0.0, weight_normalization=normalization)
        update = make_update(loss, implementation)
        batch = make_batch(UNIT, seed=3)
        w = torch.linspace(0.05, 1.0, B)
        batch["priority_weight"] = w

        def reduce(row_loss):
            return (w * row_loss).mean() if normalization == "count" else (w * row_loss).sum() / w.sum()

        with torch.no_grad():
            critic_loss = reduce(squared_one_step_errors(loss, batch).sum(0))
            with loss.actor_network_params.to_module(loss.actor_network):
                action = loss.actor_network(batch.select("observation").clone())["action"]
            actor_loss = reduce(-q_value(loss, loss.qvalue_network_params[0], batch["observation"], action))
            torch.testing.assert_close(loss.actor_loss(batch)[0], actor_loss, rtol=1e-5, atol=1e-6)
        metrics = update(batch, update_actor=False)
        torch.testing.assert_close(metrics["loss_qvalue"], critic_loss, rtol=1e-5, atol=1e-6)
        # the two differ by the weights' mean: PER's steps shrink with weights below 1
        ratio = (w.mean() if normalization == "count" else 1 / w.mean()).item()
        other = make_loss(UNIT, policy_noise=0.0, weight_normalization={"count": "sum", "sum": "count"}[normalization])
        other.load_state_dict(loss.state_dict())
        with torch.no_grad():
            torch.testing.assert_close(loss.actor_loss(batch)[0], ratio * other.actor_loss(batch)[0], rtol=1e-5, atol=0)

    def test_td_error_is_refused_with_cudagraphs(self):
        with pytest.raises(ValueError, match="td_error=True writes into the batch"):
            make_update(make_loss(UNIT), "fused", td_error=True, cudagraphs=True)

    def test_fused_equals_plain_td3loss(self):
        assert_same(run_both(UNIT, loss_kwargs={"cls": TD3Loss}))

    @pytest.mark.parametrize("device", DEVICES)
    def test_fused_equals_loss_steps_to_next_obs(self, device):
        # n-step transitions (e.g. TorchRL's MultiStepTransform): gamma ** steps_to_next_obs
        assert_same(run_both(UNIT, device=device, batch_kwargs={"steps_key": "steps_to_next_obs"}))

    def test_fused_reads_the_estimators_steps_key(self):
        # the step count is read where the loss's TD0Estimator reads it, renamed or not
        torch.manual_seed(0)
        base = make_loss(UNIT)
        base.value_estimator.set_keys(steps_to_next_obs=("my", "steps"))
        out = {}
        for implementation in ("loss", "fused"):
            update = make_update(copy.deepcopy(base), implementation)
            torch.manual_seed(1)
            out[implementation] = [
                update(make_batch(UNIT, seed=i, steps_key=("my", "steps")), update_actor=False) for i in range(2)
            ]
        for a, b in zip(out["loss"], out["fused"], strict=True):
            torch.testing.assert_close(b["loss_qvalue"], a["loss_qvalue"], atol=1e-5, rtol=1e-5)

    @pytest.mark.parametrize("device", DEVICES)
    @pytest.mark.parametrize(
        "loss_kwargs, set_keys",
        [
            ({}, None),
            ({"mixing": "weights", "alpha": 0.3}, None),  # per-row weights in both losses
            ({"loss_function": "smooth_l1"}, {"terminated": "done"}),  # the example's truncation_is_terminal
        ],
    )
    def test_fused_equals_loss_nstep(self, device, loss_kwargs, set_keys):
        # DDPGfD's critic: L_1 + lambda_1 L_n on the same rows
        out = run_both(
            UNIT,
            device=device,
            loss_kwargs=loss_kwargs,
            set_keys=set_keys,
            batch_kwargs={"nstep": True},
            nstep_key="next_n",
            nstep_weight=0.7,
        )
        assert "loss_qvalue_nstep" in out["fused"][0][0]
        assert_same(out)

    def test_first_step_by_hand(self):
        """One critic step against a hand-written TD3 target and MSE on the loss's parameters."""
        torch.manual_seed(0)
        loss = make_loss(UNIT, num_cells=(8,))
        update = make_update(loss, "fused")
        grads = recording(update)
        batch = make_batch(UNIT, seed=3)
        params = {k: v.detach().clone() for k, v in loss.state_dict().items()}

        def mlp(prefix, x, i=None):
            w = [params[f"{prefix}.{n}.weight"] for n in (0, 2)]
            b = [params[f"{prefix}.{n}.bias"] for n in (0, 2)]
            if i is not None:
                w, b = [t[i] for t in w], [t[i] for t in b]
            return torch.relu(x @ w[0].T + b[0]) @ w[1].T + b[1]

        torch.manual_seed(5)
        noise = (torch.randn(B, ACT) * 0.2).clamp(-0.5, 0.5)
        next_obs, obs, act = batch["next", "observation"], batch["observation"], batch["action"]
        next_act = (mlp("target_actor_network_params.module.0.module", next_obs).tanh() + noise).clamp(-1, 1)
        next_q = torch.min(
            *[mlp("target_qvalue_network_params.module", torch.cat([next_act, next_obs], -1), i) for i in range(2)]
        )
        y = batch["next", "reward"] + 0.9 * (~batch["next", "terminated"]) * next_q
        q = [mlp("qvalue_network_params.module", torch.cat([act, obs], -1), i) for i in range(2)]
        expected = sum(((qi - y) ** 2).mean() for qi in q)
        torch.manual_seed(5)
        metrics = update(batch, update_actor=False)
        torch.testing.assert_close(metrics["loss_qvalue"], expected)
        assert len(grads) == 1  # the critic step only

    @pytest.mark.parametrize("implementation", ["fused", "loss"])
    def test_nstep_critic_step_by_hand(self, implementation):
        """DDPGfD's two-loss critic step against hand-written TD3 targets, gamma^k for the n-step one.

        A ("next", "steps_to_next_obs") entry is not where TorchRL's estimator reads the step
        count (the root is): it changes nothing, in either implementation."""
        torch.manual_seed(0)
        loss = make_loss(UNIT, num_cells=(8,))
        update = make_update(loss, implementation, nstep_key="next_n", nstep_weight=0.7)
        batch = make_batch(UNIT, seed=3, nstep=True)
        batch["next", "steps_to_next_obs"] = torch.full((B, 1), 5)
        params = {k: v.detach().clone() for k, v in loss.state_dict().items()}

        def mlp(prefix, x, i=None):
            w = [params[f"{prefix}.{n}.weight"] for n in (0, 2)]
            b = [params[f"{prefix}.{n}.bias"] for n in (0, 2)]
            if i is not None:
                w, b = [t[i] for t in w], [t[i] for t in b]
            return torch.relu(x @ w[0].T + b[0]) @ w[1].T + b[1]

        def target(nxt, noise, gamma):
            next_obs = nxt["observation"]
            next_act = (mlp("target_actor_network_params.module.0.module", next_obs).tanh() + noise).clamp(-1, 1)
            next_q = torch.min(
                *[mlp("target_qvalue_network_params.module", torch.cat([next_act, next_obs], -1), i) for i in range(2)]
            )
            return nxt["reward"] + gamma * (~nxt["terminated"]) * next_q

        torch.manual_seed(5)
        noise_1, noise_n = [(torch.randn(B, ACT) * 0.2).clamp(-0.5, 0.5) for _ in range(2)]
        y_1 = target(batch["next"], noise_1, 0.9)
        y_n = target(batch["next_n"], noise_n, 0.9 ** batch["next_n", "steps_to_next_obs"].float())
        q = [
            mlp("qvalue_network_params.module", torch.cat([batch["action"], batch["observation"]], -1), i)
            for i in range(2)
        ]
        loss_n = sum(((qi - y_n) ** 2).mean() for qi in q)
        expected = sum(((qi - y_1) ** 2).mean() for qi in q) + 0.7 * loss_n
        torch.manual_seed(5)
        metrics = update(batch, update_actor=False)
        torch.testing.assert_close(metrics["loss_qvalue"], expected)
        torch.testing.assert_close(metrics["loss_qvalue_nstep"], loss_n)

    def test_actor_step_moves_targets_by_tau(self):
        torch.manual_seed(0)
        loss = make_loss(UNIT)
        update = make_update(loss, "fused")
        before = {k: v.clone() for k, v in loss.state_dict().items()}
        update(make_batch(UNIT, seed=0), update_actor=False)
        after_critic = loss.state_dict()
        for key in before:  # a critic step leaves the actor and every target alone
            if key.startswith(("target_", "actor_network_params")):
                torch.testing.assert_close(after_critic[key], before[key], rtol=0, atol=0)
        update(make_batch(UNIT, seed=1), update_actor=True)
        after = loss.state_dict()
        for key in before:
            if key.startswith("target_") and key.endswith(("weight", "bias")):
                source = after[key[len("target_") :]]
                torch.testing.assert_close(after[key], before[key] + 0.05 * (source - before[key]))

    @pytest.mark.parametrize("implementation", ["fused", "loss"])
    def test_actor_gradient_clipped_to_its_global_norm(self, implementation):
        # With SGD at lr 1 an actor step moves the parameters by minus the (clipped) gradient:
        # a tiny bound makes the whole move's norm exactly that bound.
        torch.manual_seed(0)
        loss = make_loss(UNIT)
        params = list(loss.actor_network_params.flatten_keys().values())
        update = TD3Update(
            loss,
            critic_optimizer=torch.optim.SGD(loss.qvalue_network_params.flatten_keys().values(), lr=1.0),
            actor_optimizer=torch.optim.SGD(params, lr=1.0),
            target_updater=SoftUpdate(loss, tau=0.05),
            implementation=implementation,
            actor_max_grad_norm=1e-3,
        )
        before = [p.detach().clone() for p in params]
        update.actor_step(make_batch(UNIT, seed=0))
        moved = torch.cat([(p.detach() - b).flatten() for p, b in zip(params, before, strict=True)])
        assert moved.norm().item() == pytest.approx(1e-3, rel=1e-4)
        with pytest.raises(ValueError, match="actor_max_grad_norm must be > 0"):
            make_update(make_loss(UNIT), implementation, actor_max_grad_norm=0.0)

    def test_fused_equals_loss_with_actor_clipping(self):
        assert_same(run_both(UNIT, actor_max_grad_norm=0.5))

    @pytest.mark.parametrize("mixing", ["batch", "weights"])
    def test_fused_equals_loss_preactivation_penalty(self, mixing):
        out = run_both(UNIT, loss_kwargs={"preactivation_coef": 0.05, "mixing": mixing, "alpha": 0.3})
        assert_same(out)
        assert "preactivation_penalty" in out["fused"][0][0] and "preactivation_penalty" not in out["fused"][0][1]

    @pytest.mark.parametrize("implementation", ["fused", "loss"])
    def test_preactivation_penalty_by_hand(self, implementation):
        # A zero critic has dQ/da = 0: with SGD at lr 1 the actor's output bias b moves by
        # -coef * d/db mean_rows sum_j x_j^2 = -coef * 2 * mean_rows x, x = the pre-tanh output.
        torch.manual_seed(0)
        coef = 0.1
        loss = make_loss(UNIT, preactivation_coef=coef)
        with torch.no_grad():
            for p in loss.qvalue_network_params.flatten_keys().values():
                p.zero_()
        params = loss.actor_network_params.flatten_keys()
        update = TD3Update(
            loss,
            critic_optimizer=torch.optim.SGD(loss.qvalue_network_params.flatten_keys().values(), lr=1.0),
            actor_optimizer=torch.optim.SGD(params.values(), lr=1.0),
            target_updater=SoftUpdate(loss, tau=0.05),
            implementation=implementation,
        )
        batch = make_batch(UNIT, seed=0)
        bias_key = next(k for k in params.keys() if k.endswith("bias") and params[k].shape == (ACT,))
        with torch.no_grad(), loss.actor_network_params.to_module(loss.actor_network):
            x = loss.actor_network(batch.select("observation").copy())["param"]
        bias = params[bias_key].detach().clone()
        metrics = update.actor_step(batch)
        torch.testing.assert_close(params[bias_key].detach(), bias - coef * 2 * x.mean(0))
        torch.testing.assert_close(metrics["preactivation_penalty"], x.pow(2).sum(-1).mean())
        torch.testing.assert_close(metrics["loss_actor"], coef * x.pow(2).sum(-1).mean())  # -Q = 0

    @pytest.mark.parametrize("nstep", [False, True])
    def test_no_host_sync(self, nstep):
        """The fused step never reads a tensor value on the host (device-agnostic check).

        With fused Adam, as the example uses: the default single-tensor Adam reads its step
        counter with ``.item()``. Also DDPGfD's two-loss critic step (``nstep``)."""
        torch.manual_seed(0)
        loss = make_loss(UNIT, mixing="weights")
        update = make_update(loss, "fused", fused_adam=True, **({"nstep_key": "next_n"} if nstep else {}))
        batch = make_batch(UNIT, seed=0, nstep=nstep)
        update(batch, update_actor=True)  # first call: optimizer state allocation
        with _HostReads() as reads:
            update(batch, update_actor=True)
            update(batch, update_actor=False)
        assert reads.calls == []

    def test_bf16_close_to_fp32(self):
        """Reduced precision: losses within 5% and gradients within 5% (relative norm) of fp32."""
        torch.manual_seed(0)
        base = make_loss(UNIT, num_cells=(64, 64))
        results = {}
        for precision in ("fp32", "bf16"):
            update = make_update(copy.deepcopy(base), "fused", precision=precision)
            grads = recording(update)
            torch.manual_seed(1)
            results[precision] = (update(make_batch(UNIT, seed=0), update_actor=True), grads)
        (m32, g32), (m16, g16) = results["fp32"], results["bf16"]
        for key in m32:
            torch.testing.assert_close(m16[key], m32[key], rtol=0.05, atol=1e-2, msg=key)
        for step32, step16 in zip(g32, g16, strict=True):
            for a, b in zip(step32, step16, strict=True):
                if a is not None:
                    assert (b - a).norm() <= 0.05 * a.norm() + 1e-6
        # bf16 actually ran: the losses differ from fp32 beyond float32 rounding
        assert not torch.equal(m16["loss_qvalue"], m32["loss_qvalue"])

    def test_bf16_layer_norm_critics_run_as_their_modules_under_autocast(self):
        """A LayerNorm critic's bf16 step against each critic's own ``nn.Module`` under autocast:
        its Q within 1e-2 and its first-layer gradient within 1%, closer to the module's than to
        float32 (a norm divides by the features' spread, so bf16's rounding of the products before
        it shows more than without one). The fused step keeps the norm in float32 where CPU
        autocast rounds its output to bfloat16: the two differ by that rounding alone."""
        loss = make_loss(UNIT, num_cells=(64, 64), layer_norm=True)
        update = make_update(loss, "fused", precision="bf16")
        batch = make_batch(UNIT, seed=0)
        x = torch.cat([batch["action"], batch["observation"]], -1)
        params = loss.qvalue_network_params.detach().clone().apply(lambda t: t.requires_grad_(True))
        program = td3_update._mlp_program(loss.qvalue_network.module, params["module"], "critic")
        with torch.autocast("cpu", dtype=torch.bfloat16):
            q = td3_update._run(program, x).squeeze(-1)
        (grad,) = torch.autograd.grad(q.square().sum(), params["module", "0", "weight"])
        for i in (0, 1):
            module = copy.deepcopy(loss.qvalue_network.module)
            params[i]["module"].detach().to_module(module)
            module.requires_grad_(True)
            references = {}
            for name, autocast in (("bf16", True), ("fp32", False)):
                module.zero_grad()
                with torch.autocast("cpu", dtype=torch.bfloat16, enabled=autocast):
                    q_i = module(x).squeeze(-1)
                q_i.float().square().sum().backward()
                references[name] = (q_i.float().detach(), module[0].weight.grad.clone())
            (q16, g16), (_, g32) = references["bf16"], references["fp32"]
            torch.testing.assert_close(q[i], q16, rtol=1e-2, atol=1e-2)
            assert (grad[i] - g16).norm() <= 0.01 * g16.norm()
            assert (grad[i] - g16).norm() < (grad[i] - g32).norm()
        assert update.precision == "bf16"

    def test_bf16_critic_output_not_rounded(self):
        """Under bf16 the critics' last layer runs in float32: Q near 100 is not rounded to bfloat16's 0.5 grid.

        With the last bias at 100.3 and small hidden contributions, a bfloat16 output could only
        be 100.0 or 100.5; the fused step's Q must stay within the hidden layers' rounding (1e-2)."""
        torch.manual_seed(0)
        base = make_loss(UNIT, num_cells=(64, 64))
        with torch.no_grad():
            for name in ("qvalue_network_params", "target_qvalue_network_params"):
                getattr(base, name)["module", "4", "bias"].fill_(100.3)
        q = {}
        for precision in ("fp32", "bf16"):
            update = make_update(copy.deepcopy(base), "fused", precision=precision)
            torch.manual_seed(1)
            q[precision] = update.critic_step(make_batch(UNIT, seed=0))["q_mean"]
        assert 99.0 < q["fp32"] < 102.0
        assert (q["bf16"] - q["fp32"]).abs() < 1e-2
        assert q["bf16"] != q["fp32"]  # the hidden layers did run in bfloat16

    def test_bf16_actor_gradient_survives_saturation(self):
        """The actor's tanh runs in float32 under bf16: a saturating policy keeps its gradient.

        With pre-activations around 4, bfloat16 rounds tanh to exactly 1 and its gradient to 0,
        while float32 still has 1 - tanh(4)^2 = 1.3e-3: the actor would stop learning."""
        torch.manual_seed(0)
        base = make_loss(UNIT, num_cells=(64, 64))
        with torch.no_grad():
            base.actor_network_params["module", "0", "module", "4", "bias"].fill_(4.0)
        grads = {}
        for precision in ("fp32", "bf16"):
            update = make_update(copy.deepcopy(base), "fused", precision=precision)
            recorded = recording(update)
            update.actor_step(make_batch(UNIT, seed=0))
            grads[precision] = torch.cat([g.flatten() for g in recorded[-1] if g is not None])
        assert grads["fp32"].norm() > 0
        assert (grads["bf16"] - grads["fp32"]).norm() <= 0.05 * grads["fp32"].norm()

    @pytest.mark.parametrize(
        "move, layer_norm",
        [("to_float64", False), ("to_float64", True), ("swap_tensors", False), ("new_estimator", False)]
        + [("estimator_keys", False)],
    )
    def test_follows_the_loss_after_binding(self, move, layer_norm):
        """What the fused step bound moves after it is built: it binds again and still equals the reference
        (a LayerNorm net in float64 too: its norm runs in float64).

        Without binding again, its Polyak step would move the old float32 storage and its actor
        loss read a stale critic, with no error."""
        torch.manual_seed(0)
        base = make_loss(UNIT, layer_norm=layer_norm)
        out = {}
        for implementation in ("loss", "fused"):
            loss = copy.deepcopy(base)
            update = make_update(loss, implementation)
            dtype = torch.float32
            if move == "to_float64":
                loss.to(torch.float64)
                dtype = torch.float64
            elif move == "swap_tensors":  # new storage under the same parameter objects (not the tanh bounds)
                for params in (loss.qvalue_network_params, loss.target_actor_network_params):
                    for key, param in params.items(True, True):
                        if key[-1] in ("weight", "bias"):
                            torch.utils.swap_tensors(param, nn.Parameter(param.detach() + 0.1, param.requires_grad))
            elif move == "new_estimator":
                loss.make_value_estimator(gamma=0.5)
            else:
                loss.value_estimator.set_keys(reward="shaped", terminated="ended", done="over")
            grads = recording(update)
            torch.manual_seed(1)
            metrics = []
            for i in range(4):
                batch = make_batch(UNIT, seed=i).apply(
                    lambda t, dtype=dtype: t.to(dtype) if t.is_floating_point() else t
                )
                batch["next", "shaped"] = 10 + batch["next", "reward"]
                batch["next", "ended"] = ~batch["next", "terminated"]
                batch["next", "over"] = batch["next", "ended"] | batch["next", "truncated"]
                metrics.append(update(batch, update_actor=i % 2 == 0))
            out[implementation] = (metrics, grads, loss.state_dict())
        assert_same(out, atol=1e-5)
        state = out["fused"][2]
        assert state["target_qvalue_network_params.module.0.weight"].dtype == (
            torch.float64 if move == "to_float64" else torch.float32
        )

    def test_refuses_what_it_cannot_bind_again(self):
        loss = make_loss(UNIT)
        update = make_update(loss, "fused")
        update(make_batch(UNIT, seed=0), update_actor=True)
        loss.make_value_estimator(gamma=0.9, lmbda=0.9, value_type="tdlambda")
        with pytest.raises(ValueError, match="TD\\(0\\) target"):
            update(make_batch(UNIT, seed=1), update_actor=True)

    @pytest.mark.parametrize("layer_norm", [False, True])
    def test_compiled_equals_eager(self, layer_norm):
        """torch.compile of the whole step (TorchRL's compile_with_warmup pattern) gives the same step."""
        import torch._inductor.config as inductor_config

        torch.manual_seed(0)
        base = make_loss(UNIT, num_cells=(8,), layer_norm=layer_norm)
        states = []
        for compiled in (False, True):
            loss = copy.deepcopy(base)
            update = make_update(loss, "fused")
            step = torch.compile(update.__call__) if compiled else update
            torch.manual_seed(1)
            with inductor_config.patch(fallback_random=True):  # eager's RNG stream in compiled code
                for i in range(3):
                    step(make_batch(UNIT, seed=i), update_actor=i % 2 == 0)
            states.append(loss.state_dict())
        for key in states[0]:
            torch.testing.assert_close(states[1][key], states[0][key], rtol=1e-5, atol=1e-6, msg=key)

    def test_refuses_unsupported(self):
        loss = make_loss(UNIT)
        loss.qvalue_network.module.append(nn.BatchNorm1d(1))
        with pytest.raises(TypeError, match="BatchNorm1d at position 5"):
            make_update(loss, "fused")
        make_update(loss, "loss")  # the reference runs any network
        with pytest.raises(ValueError, match="implementation must be 'fused' or 'loss'"):
            make_update(make_loss(UNIT), "fast")
        with pytest.raises(ValueError, match="precision must be one of"):
            make_update(make_loss(UNIT), "fused", precision="fp16")
        with pytest.raises(ValueError, match="needs implementation='fused'"):
            make_update(make_loss(UNIT), "loss", precision="bf16")

        td1 = make_loss(UNIT)
        td1.make_value_estimator(gamma=0.9, lmbda=0.9, value_type="tdlambda")
        with pytest.raises(ValueError, match="TD\\(0\\) target"):
            make_update(td1, "fused")
        # TD(0) settings the fused step does not compute: refused, not approximated
        averaged = make_loss(UNIT)
        averaged.make_value_estimator(gamma=0.9, average_rewards=True)
        with pytest.raises(ValueError, match="average_rewards=True"):
            make_update(averaged, "fused")
        make_update(averaged, "loss")
        own_net = make_loss(UNIT)
        own_net.make_value_estimator(TD0Estimator(gamma=0.9, value_network=own_net.qvalue_network))
        with pytest.raises(ValueError, match="its own value_network"):
            make_update(own_net, "fused")
        renamed = make_loss(UNIT)
        renamed.value_estimator.set_keys(value="other_value")
        with pytest.raises(ValueError, match="reads the next value from 'other_value'"):
            make_update(renamed, "fused")
        with pytest.raises(ValueError, match="needs the loss on a CUDA device, got cpu"):
            make_update(make_loss(UNIT), "fused", cudagraphs=True)
        with pytest.raises(ValueError, match="cudagraphs=True replays the fused step"):
            make_update(make_loss(UNIT), "loss", cudagraphs=True)
        for kwargs, match in [
            ({"nstep_key": "next"}, "nstep_key='next' is the 1-step"),
            ({"nstep_key": "next_n", "nstep_weight": 0.0}, "lambda_1\\) must be a finite number > 0"),
            ({"nstep_key": "next_n", "nstep_weight": float("nan")}, "must be a finite number"),
        ]:
            with pytest.raises(ValueError, match=match):
                make_update(make_loss(UNIT), "loss", **kwargs)

    def test_bf16_warns_without_bf16_hardware(self, monkeypatch):
        import torchrl_sail.objectives.td3_update as td3_update

        monkeypatch.setattr(td3_update, "native_bf16_matmul", lambda device: False)
        with pytest.warns(UserWarning, match="precision='bf16' on a cpu without bf16 matrix hardware"):
            make_update(make_loss(UNIT), "fused", precision="bf16")
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            make_update(make_loss(UNIT), "fused", precision="fp32")  # fp32 has nothing to warn about
            monkeypatch.setattr(td3_update, "native_bf16_matmul", lambda device: True)
            make_update(make_loss(UNIT), "fused", precision="bf16")


class _HostReads(TorchFunctionMode):
    """Records calls that copy a tensor value to the host (a device synchronisation on CUDA)."""

    _SYNCING = {
        torch.Tensor.item,
        torch.Tensor.tolist,
        torch.Tensor.__bool__,
        torch.Tensor.__int__,
        torch.Tensor.__float__,
        torch.Tensor.nonzero,
        torch.nonzero,
        torch.masked_select,
        torch.Tensor.masked_select,
        torch.Tensor.numpy,
    }

    def __enter__(self):
        self.calls = []
        return super().__enter__()

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if func in self._SYNCING:
            self.calls.append(func.__name__)
        if func is torch.Tensor.__getitem__ and any(
            isinstance(i, torch.Tensor) and i.dtype == torch.bool
            for i in (args[1] if isinstance(args[1], tuple) else (args[1],))
        ):
            self.calls.append("boolean indexing")
        return func(*args, **kwargs)


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="CUDA graphs need a CUDA device")
class TestCudaGraphs:
    """The fused step replayed as CUDA graphs equals the same step run eagerly."""

    def run(self, cudagraphs, *, steps=10, precision="fp32", change=None, loss_kwargs=None):
        torch.manual_seed(0)
        loss = make_loss(UNIT, device="cuda", **(loss_kwargs or {}))
        update = make_update(
            loss, "fused", capturable=True, precision=precision, cudagraphs=cudagraphs, cudagraph_warmup=2
        )
        torch.manual_seed(1)  # the policy-smoothing noise, drawn inside the graph too
        metrics = []
        for i in range(steps):
            if change is not None and i == steps // 2:
                change(update)
            metrics.append(update(make_batch(UNIT, seed=i, device="cuda"), update_actor=i % 2 == 0))
        return update, metrics, loss.state_dict()

    def assert_same(self, eager, graphed, atol=1e-6):
        for a, b in zip(eager[1], graphed[1], strict=True):
            assert a.keys() == b.keys()
            for key in a:
                torch.testing.assert_close(b[key], a[key], atol=atol, rtol=1e-5, msg=key)
        for key in eager[2]:
            torch.testing.assert_close(graphed[2][key], eager[2][key], atol=atol, rtol=1e-5, msg=key)

    @pytest.mark.parametrize("precision", ["fp32", "bf16"])
    def test_graphed_equals_eager(self, precision):
        graphed = self.run(True, precision=precision)
        # two graphs (critic steps, and critic + actor + target steps), captured and replayed
        assert sorted(graphed[0]._graphs) == [False, True]
        assert all(hasattr(graph, "graph") for graph in graphed[0]._graphs.values())
        self.assert_same(self.run(False, precision=precision), graphed)

    def test_graphed_weights_mixing_follows_alpha(self):
        # alpha is a buffer the graph reads: scheduling it in place reaches the replays
        def schedule(update):
            update.loss.alpha.fill_(0.8)

        kwargs = {"loss_kwargs": {"mixing": "weights", "alpha": 0.3}, "change": schedule}
        self.assert_same(self.run(False, **kwargs), self.run(True, **kwargs))

    def test_recaptured_after_a_new_learning_rate(self):
        # a graph holds the lr it was captured with: a new one is captured again, not ignored
        def decay(update):
            for group in update.actor_optimizer.param_groups:
                group["lr"] = 1e-3

        self.assert_same(self.run(False, change=decay), self.run(True, change=decay))

    def test_refuses_a_non_capturable_optimizer(self):
        with pytest.raises(ValueError, match="critic_optimizer built with capturable=True"):
            make_update(make_loss(UNIT, device="cuda"), "fused", cudagraphs=True)
