"""Tests for SAILLoss (objectives/sail.py) and AlphaScheduler (objectives/alpha.py).

The weighted form (``mixing="weights"``) is tested against hand-written references; the
default batch form must be exactly TorchRL's TD3Loss."""

from __future__ import annotations

import argparse
import warnings

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.data import Bounded
from torchrl.modules import MLP, TanhModule, ValueOperator
from torchrl.objectives import SoftUpdate, TD3Loss

from torchrl_sail import AlphaScheduler, SAILLoss

OBS, ACT, HIDDEN = 3, 2, 8
GAMMA = 0.9
SPEC = Bounded(-torch.ones(ACT), torch.ones(ACT), (ACT,))


def make_nets():
    """Actor/critic built like TorchRL's sota TD3 (materialised: no lazy layers)."""
    actor = TensorDictSequential(
        TensorDictModule(
            MLP(
                in_features=OBS,
                out_features=ACT,
                num_cells=[HIDDEN],
                activation_class=torch.nn.ReLU,
            ),
            ["observation"],
            ["param"],
        ),
        TanhModule(["param"], ["action"], spec=SPEC),
    )
    critic = ValueOperator(
        MLP(
            in_features=OBS + ACT,
            out_features=1,
            num_cells=[HIDDEN],
            activation_class=torch.nn.ReLU,
        ),
        in_keys=["action", "observation"],
    )
    return actor, critic


def make_loss(cls=SAILLoss, *, perturb_targets=True, **kwargs):
    kwargs.setdefault("loss_function", "l2")
    if cls is SAILLoss:
        kwargs.setdefault("mixing", "weights")
    actor, critic = make_nets()
    loss = cls(actor, critic, action_spec=SPEC, **kwargs)
    loss.make_value_estimator(gamma=GAMMA)
    SoftUpdate(loss, tau=0.1)  # marks the targets as updated: no no-updater warning
    if perturb_targets:
        # Targets start as copies of the online nets; make them differ so a reference that
        # mixed up online and target parameters would not match.
        g = torch.Generator().manual_seed(123)
        for name, buf in loss.named_buffers():
            if name.startswith("target_") and name.endswith(("weight", "bias")):
                buf.add_(0.3 * torch.randn(buf.shape, generator=g))
    return loss


def copy_params(dst, src):
    """Give ``dst`` exactly the (re-sampled) parameters and targets of ``src``."""
    state = {k: v for k, v in src.state_dict().items() if k != "alpha"}
    result = dst.load_state_dict(state, strict=False)
    assert result.unexpected_keys == []
    assert set(result.missing_keys) <= {"alpha"}


def make_batch(n_teacher, n_agent, *, seed=0, tag_key="is_teacher"):
    g = torch.Generator().manual_seed(seed)
    b = n_teacher + n_agent
    terminated = torch.rand(b, 1, generator=g) < 0.3
    tag = torch.zeros(b, dtype=torch.bool)
    tag[:n_teacher] = True
    return TensorDict(
        {
            "observation": torch.randn(b, OBS, generator=g),
            # some actions at the bounds so the target-action clamp matters
            "action": (torch.rand(b, ACT, generator=g) * 2.4 - 1.2).clamp(-1, 1),
            tag_key: tag,
            ("next", "observation"): torch.randn(b, OBS, generator=g),
            ("next", "reward"): torch.randn(b, 1, generator=g),
            ("next", "terminated"): terminated,
            ("next", "done"): terminated.clone(),
        },
        [b],
    )


def q_params(loss):
    return list(loss.qvalue_network_params.values(True, True))


def actor_params(loss):
    return [p for p in loss.actor_network_params.values(True, True) if isinstance(p, torch.nn.Parameter)]


def grads(out, params):
    return torch.autograd.grad(out, params, retain_graph=True)


def assert_close_all(xs, ys, **kw):
    assert len(xs) == len(ys)
    for x, y in zip(xs, ys, strict=True):
        torch.testing.assert_close(x, y, **kw)


def td3_per_row(loss_sail, batch):
    """Per-row TD3 (l2) actor and critic terms with the same parameters, no noise."""
    td3 = make_loss(TD3Loss, reduction="none", policy_noise=0.0, perturb_targets=False)
    copy_params(td3, loss_sail)
    plain = batch.exclude("is_teacher", "priority_weight", ("collector", "mask"))
    out = td3(plain.clone())
    return out["loss_actor"].detach(), out["loss_qvalue"].detach()


# ------------------------------------------------------------------ hand reference


def mlp(x, p):
    """Hand-written forward of MLP(num_cells=[HIDDEN]) = Linear, ReLU, Linear."""
    h = torch.relu(x @ p["0", "weight"].transpose(-1, -2) + p["0", "bias"].unsqueeze(-2))
    return h @ p["2", "weight"].transpose(-1, -2) + p["2", "bias"].unsqueeze(-2)


def actor_fwd(obs, params):
    return torch.tanh(mlp(obs, params["module", "0", "module"]))  # bounds are [-1, 1]


def q_fwd(obs, act, params):
    """All Q-nets at once: params are stacked [num_q, ...] -> [num_q, B]."""
    x = torch.cat([act, obs], -1).expand(params["module", "0", "weight"].shape[0], -1, -1)
    return mlp(x, params["module"]).squeeze(-1)


def reference(loss, batch, alpha, noise):
    tag = batch["is_teacher"]
    n_t, n_s = int(tag.sum()), int((~tag).sum())
    w = torch.where(tag, alpha / max(n_t, 1), (1 - alpha) / max(n_s, 1))
    obs, act = batch["observation"], batch["action"]
    nobs = batch["next", "observation"]
    r = batch["next", "reward"].squeeze(-1)
    not_term = (~batch["next", "terminated"]).squeeze(-1).float()
    with torch.no_grad():
        next_act = (actor_fwd(nobs, loss.target_actor_network_params) + noise).clamp(-1, 1)
        next_q = q_fwd(nobs, next_act, loss.target_qvalue_network_params).min(0).values
        y = r + GAMMA * not_term * next_q
    q = q_fwd(obs, act, loss.qvalue_network_params)  # [2, B]
    critic = ((q - y) ** 2 * w).sum(-1).sum(0)
    pi = actor_fwd(obs, loss.actor_network_params)
    q_pi = q_fwd(obs, pi, loss.qvalue_network_params.detach())  # critic gets no grad
    actor = -(q_pi[0] * w).sum()
    return actor, critic


# ------------------------------------------------------------------ SAILLoss math


class _Holder:
    alpha = 1.0


def _roundtrip(obj):
    import io

    buf = io.BytesIO()
    torch.save(obj, buf)
    buf.seek(0)
    return buf


class TestSAILLoss:
    @pytest.mark.parametrize("alpha", [0.0, 0.3, 1.0])
    def test_batch_mixing_is_exactly_td3(self, alpha):
        # mixing="batch": alpha acts through the batch composition, the loss is TD3Loss itself
        sail = make_loss(alpha=alpha, mixing="batch", policy_noise=0.0)
        td3 = make_loss(TD3Loss, policy_noise=0.0, perturb_targets=False)
        copy_params(td3, sail)
        batch = make_batch(3, 5, seed=21)
        out_s, out_t = sail(batch.clone()), td3(batch.exclude("is_teacher"))
        for key in ("loss_qvalue", "loss_actor"):
            torch.testing.assert_close(out_s[key], out_t[key], rtol=0, atol=0)
        assert_close_all(
            grads(out_s["loss_qvalue"], q_params(sail)), grads(out_t["loss_qvalue"], q_params(td3)), rtol=0, atol=0
        )
        assert "is_teacher" not in sail.in_keys and float(out_s["alpha"]) == pytest.approx(alpha)
        assert sail(batch.exclude("is_teacher"))["loss_qvalue"] == out_s["loss_qvalue"]  # no tag needed

    def test_alpha0_equals_td3_on_agent_rows(self):
        sail = make_loss(alpha=0.0, policy_noise=0.0)
        td3 = make_loss(TD3Loss, policy_noise=0.0, perturb_targets=False)
        copy_params(td3, sail)
        batch = make_batch(3, 5)
        tag = batch["is_teacher"]
        sail_in = batch.clone()
        out_s = sail(sail_in)
        out_t = td3(batch[~tag].exclude("is_teacher"))
        torch.testing.assert_close(out_s["loss_qvalue"], out_t["loss_qvalue"])
        torch.testing.assert_close(out_s["loss_actor"], out_t["loss_actor"])
        assert_close_all(
            grads(out_s["loss_qvalue"], q_params(sail)),
            grads(out_t["loss_qvalue"], q_params(td3)),
        )
        assert_close_all(
            grads(out_s["loss_actor"], actor_params(sail)),
            grads(out_t["loss_actor"], actor_params(td3)),
        )
        # the teacher rows really are in the batch, they just weigh nothing
        assert sail_in["td_error"].shape == (8,)
        assert float(sail_in["td_error"][:3].sum()) > 0

    def test_alpha1_only_depends_on_teacher_rows(self):
        loss = make_loss(alpha=1.0)  # default target policy noise, seeded below
        batch = make_batch(4, 3, seed=1)
        other = make_batch(4, 3, seed=2)
        changed_agent = batch.clone()
        changed_agent[4:] = other[4:]
        changed_teacher = batch.clone()
        changed_teacher[:4] = other[:4]

        def run(td):
            torch.manual_seed(5)
            out = loss(td.clone())
            g = grads(out["loss_qvalue"], q_params(loss))
            g += grads(out["loss_actor"], actor_params(loss))
            return out, g

        out_a, g_a = run(batch)
        out_b, g_b = run(changed_agent)
        torch.testing.assert_close(out_a["loss_qvalue"], out_b["loss_qvalue"])
        torch.testing.assert_close(out_a["loss_actor"], out_b["loss_actor"])
        assert_close_all(g_a, g_b)
        # ... while changing teacher rows does change it (the test can fail)
        out_c, _ = run(changed_teacher)
        assert not torch.allclose(out_a["loss_qvalue"], out_c["loss_qvalue"])
        assert not torch.allclose(out_a["loss_actor"], out_c["loss_actor"])

    @pytest.mark.parametrize("n_teacher,n_agent", [(4, 4), (3, 5)])
    def test_alpha_half_matches_hand_reference(self, n_teacher, n_agent):
        loss = make_loss(alpha=0.5, policy_noise=0.6, noise_clip=0.5)
        batch = make_batch(n_teacher, n_agent, seed=3)
        b = n_teacher + n_agent
        torch.manual_seed(11)
        out = loss(batch.clone())
        torch.manual_seed(11)  # value_loss draws randn_like(action) before anything else
        noise = (torch.randn(b, ACT) * 0.6).clamp(-0.5, 0.5)
        ref_actor, ref_critic = reference(loss, batch, 0.5, noise)
        torch.testing.assert_close(out["loss_qvalue"], ref_critic)
        torch.testing.assert_close(out["loss_actor"], ref_actor)
        assert_close_all(grads(out["loss_qvalue"], q_params(loss)), grads(ref_critic, q_params(loss)))
        assert_close_all(grads(out["loss_actor"], actor_params(loss)), grads(ref_actor, actor_params(loss)))
        # the actor loss reaches no critic parameter
        assert all(
            g is None
            for g in torch.autograd.grad(out["loss_actor"], q_params(loss), retain_graph=True, allow_unused=True)
        )

    @pytest.mark.parametrize(
        "alpha,n_teacher,n_agent",
        [(0.3, 2, 6), (0.8, 5, 1), (0.5, 1, 7), (1.0, 3, 0), (0.0, 0, 4)],
    )
    def test_unequal_group_sizes_use_per_group_means(self, alpha, n_teacher, n_agent):
        loss = make_loss(alpha=alpha, policy_noise=0.0)
        batch = make_batch(n_teacher, n_agent, seed=4)
        actor_rows, critic_rows = td3_per_row(loss, batch)
        tag = batch["is_teacher"]

        def mix(rows):
            total = torch.zeros(())
            if n_teacher:
                total = total + alpha / n_teacher * rows[tag].sum()
            if n_agent:
                total = total + (1 - alpha) / n_agent * rows[~tag].sum()
            return total

        out = loss(batch.clone())
        torch.testing.assert_close(out["loss_qvalue"], mix(critic_rows))
        torch.testing.assert_close(out["loss_actor"], mix(actor_rows))

    def test_balanced_batch_with_matching_alpha_is_exactly_td3(self):
        # the authors' setting: 128 + 128 rows, alpha = 0.5, plain mean over the batch
        sail = make_loss(alpha=0.5, policy_noise=0.0)
        td3 = make_loss(TD3Loss, policy_noise=0.0, perturb_targets=False)
        copy_params(td3, sail)
        batch = make_batch(8, 8, seed=6)
        out_s, out_t = sail(batch.clone()), td3(batch.exclude("is_teacher"))
        torch.testing.assert_close(out_s["loss_qvalue"], out_t["loss_qvalue"], rtol=1e-6, atol=0)
        torch.testing.assert_close(out_s["loss_actor"], out_t["loss_actor"], rtol=1e-6, atol=0)

    def test_reductions_sum_and_none(self):
        mean_loss = make_loss(alpha=0.3, policy_noise=0.0)
        batch = make_batch(2, 4, seed=7)
        out_mean = mean_loss(batch.clone())
        for reduction in ("sum", "none"):
            other = make_loss(alpha=0.3, policy_noise=0.0, reduction=reduction, perturb_targets=False)
            copy_params(other, mean_loss)
            out = other(batch.clone())
            for key in ("loss_qvalue", "loss_actor"):
                value = out[key]
                if reduction == "none":
                    # weighted per-row terms, averaging 1 per valid row: they sum to B * mean
                    assert value.shape == (6,)
                    value = value.sum()
                torch.testing.assert_close(value, 6 * out_mean[key])

    def test_prioritized_weights_are_normalised_within_groups(self):
        alpha = 0.4
        loss = make_loss(alpha=alpha, policy_noise=0.0)
        batch = make_batch(3, 4, seed=8)
        prb = torch.tensor([1.0, 0.5, 0.25, 2.0, 1.0, 1.0, 0.1])
        batch["priority_weight"] = prb
        actor_rows, critic_rows = td3_per_row(loss, batch)
        tag = batch["is_teacher"]

        def mix(rows):
            t = (prb[tag] * rows[tag]).sum() / prb[tag].sum()
            s = (prb[~tag] * rows[~tag]).sum() / prb[~tag].sum()
            return alpha * t + (1 - alpha) * s

        out = loss(batch.clone())
        torch.testing.assert_close(out["loss_qvalue"], mix(critic_rows))
        torch.testing.assert_close(out["loss_actor"], mix(actor_rows))
        # disabled PRB weights: plain per-group means
        off = make_loss(
            alpha=alpha,
            policy_noise=0.0,
            use_prioritized_weights=False,
            perturb_targets=False,
        )
        copy_params(off, loss)
        expected = alpha * critic_rows[tag].mean() + (1 - alpha) * critic_rows[~tag].mean()
        torch.testing.assert_close(off(batch.clone())["loss_qvalue"], expected)

    def test_masked_rows_are_left_out_of_the_counts(self):
        alpha = 0.5
        loss = make_loss(alpha=alpha, policy_noise=0.0)
        batch = make_batch(3, 4, seed=9)
        mask = torch.tensor([True, False, True, True, True, False, False])
        batch["collector", "mask"] = mask
        actor_rows, critic_rows = td3_per_row(loss, batch)
        tag = batch["is_teacher"]
        expected = alpha * critic_rows[tag & mask].mean() + (1 - alpha) * critic_rows[~tag & mask].mean()
        torch.testing.assert_close(loss(batch.clone())["loss_qvalue"], expected)
        # a group with no valid row contributes nothing: the agent mean alone
        mask = torch.tensor([False, False, False, True, True, True, True])
        batch["collector", "mask"] = mask
        torch.testing.assert_close(loss(batch.clone())["loss_qvalue"], critic_rows[mask].mean())

    def test_outputs_and_td_error(self):
        loss = make_loss(alpha=0.5)
        batch = make_batch(3, 5, seed=10)
        td = batch.clone()
        out = loss(td)
        td3_keys = {
            "loss_actor",
            "loss_qvalue",
            "pred_value",
            "state_action_value_actor",
            "next_state_value",
            "target_value",
        }
        assert td3_keys | {"alpha", "pred_value_teacher", "pred_value_agent"} == set(out.keys())
        assert set(make_loss(mixing="batch")(batch.clone()).keys()) == td3_keys | {"alpha"} == set(loss.out_keys)
        penalised = make_loss(mixing="batch", preactivation_coef=1e-3)
        assert set(penalised(batch.clone()).keys()) == td3_keys | {"alpha", "preactivation_penalty"}
        assert set(penalised.out_keys) == td3_keys | {"alpha", "preactivation_penalty"}
        assert set(make_loss(mixing="batch").out_keys) == td3_keys | {"alpha"}  # the class's list is unchanged
        assert td["td_error"].shape == (8,)
        pred = out["pred_value"].mean(0)
        tag = batch["is_teacher"]
        torch.testing.assert_close(out["pred_value_teacher"], pred[tag].mean())
        torch.testing.assert_close(out["pred_value_agent"], pred[~tag].mean())
        assert not out["alpha"].requires_grad
        loss.alpha = 0.0  # the logged value is a copy, not a view of the buffer
        assert float(out["alpha"]) == 0.5

    def test_dispatch_keyword_mode_matches_tensordict_mode(self):
        loss = make_loss(alpha=0.3, policy_noise=0.0)
        batch = make_batch(2, 3, seed=12)
        out = loss(batch.clone())
        loss.select_out_keys("loss_actor", "loss_qvalue", "alpha")
        loss_actor, loss_qvalue, alpha = loss(
            observation=batch["observation"],
            action=batch["action"],
            is_teacher=batch["is_teacher"],
            next_observation=batch["next", "observation"],
            next_reward=batch["next", "reward"],
            next_done=batch["next", "done"],
            next_terminated=batch["next", "terminated"],
        )
        torch.testing.assert_close(loss_actor, out["loss_actor"])
        torch.testing.assert_close(loss_qvalue, out["loss_qvalue"])
        assert float(alpha) == pytest.approx(0.3)

    # ------------------------------------------------------------------ alpha buffer

    @pytest.mark.parametrize("bad", [-0.1, 1.5, float("nan")])
    def test_alpha_out_of_range_at_construction(self, bad):
        actor, critic = make_nets()
        with pytest.raises(ValueError, match="alpha must be in \\[0, 1\\]"):
            SAILLoss(actor, critic, action_spec=SPEC, alpha=bad)

    def test_alpha_assignment_is_in_place(self):
        loss = make_loss(alpha=1)  # an int must still give a float buffer
        buf = loss.alpha
        assert buf.dtype == torch.float32
        loss.alpha = 0.25
        assert loss.alpha is buf and float(buf) == 0.25
        loss.alpha = 0.75
        assert loss.alpha is buf and float(buf) == 0.75
        assert "alpha" in dict(loss.named_buffers())
        # round-trips through the state dict like any buffer
        other = make_loss(alpha=0.5, perturb_targets=False)
        other.load_state_dict(loss.state_dict())
        assert float(other.alpha) == 0.75

    @pytest.mark.parametrize("bad", [-0.1, float("inf"), float("nan"), "1e-3", True])
    def test_preactivation_coef_out_of_range_at_construction(self, bad):
        actor, critic = make_nets()
        with pytest.raises(ValueError, match="preactivation_coef must be a finite number >= 0"):
            SAILLoss(actor, critic, action_spec=SPEC, preactivation_coef=bad)

    def test_preactivation_penalty_needs_a_tanh_actor(self):
        _, critic = make_nets()
        actor = TensorDictModule(torch.nn.Linear(OBS, ACT), ["observation"], ["action"])
        with pytest.raises(ValueError, match="without one"):
            SAILLoss(actor, critic, action_spec=SPEC, preactivation_coef=1e-3)
        SAILLoss(actor, critic, action_spec=SPEC)  # no penalty: any actor
        # a TanhModule that writes back into its input key leaves no pre-tanh output to read
        overwriting = TensorDictSequential(
            TensorDictModule(torch.nn.Linear(OBS, ACT), ["observation"], ["action"]),
            TanhModule(["action"], spec=SPEC),
        )
        with pytest.raises(ValueError, match="which the module overwrites with the action"):
            SAILLoss(overwriting, critic, action_spec=SPEC, preactivation_coef=1e-3)

    def test_loss_function_defaults_to_l2(self):
        actor, critic = make_nets()
        assert SAILLoss(actor, critic, action_spec=SPEC).loss_function == "l2"

    # ------------------------------------------------------------------ bad batches and keys

    def test_weights_need_the_tag(self):
        with pytest.raises(KeyError, match="is_teacher"):
            make_loss(alpha=0.5)(make_batch(2, 2).exclude("is_teacher"))

    def test_tag_with_a_trailing_dim_is_accepted(self):
        loss = make_loss(alpha=0.5, policy_noise=0.0)
        batch = make_batch(2, 2)
        ref = loss(batch.clone())["loss_qvalue"]
        batch["is_teacher"] = batch["is_teacher"].unsqueeze(-1)
        torch.testing.assert_close(loss(batch)["loss_qvalue"], ref)

    def test_truncated_rows_bootstrap_unless_done_is_terminal(self):
        # what load_sb_demonstrations documents for its approximated final next observation:
        # at a truncation (done, not terminated) the default target reads it, and with
        # set_keys(terminated="done") (the authors' convention) it does not
        batch = make_batch(2, 2, seed=5)
        batch["next", "terminated"] = torch.zeros(4, 1, dtype=torch.bool)
        batch["next", "done"] = torch.ones(4, 1, dtype=torch.bool)
        batch["next", "truncated"] = torch.ones(4, 1, dtype=torch.bool)
        moved = batch.clone()
        moved["next", "observation"] = moved["next", "observation"] + 5.0
        loss = make_loss(alpha=0.5, policy_noise=0.0)
        assert loss(batch)["loss_qvalue"] != loss(moved)["loss_qvalue"]
        loss.set_keys(terminated="done")
        torch.testing.assert_close(loss(batch)["loss_qvalue"], loss(moved)["loss_qvalue"], rtol=0, atol=0)

    def test_in_keys_order_is_td3_then_tag(self):
        # a set-based merge made this order depend on PYTHONHASHSEED
        td3 = make_loss(TD3Loss)
        loss = make_loss()
        assert loss.in_keys == [*td3.in_keys, "is_teacher"]
        assert len(set(loss.in_keys)) == len(loss.in_keys)
        loss.set_keys(is_teacher="src")
        assert loss.in_keys == [*td3.in_keys, "src"]
        assert make_loss(mixing="batch").in_keys == td3.in_keys

    def test_set_keys_is_teacher(self):
        loss = make_loss(alpha=0.3, policy_noise=0.0)
        ref = loss(make_batch(2, 3, seed=13))
        loss.set_keys(is_teacher="src")
        assert "src" in loss.in_keys and "is_teacher" not in loss.in_keys
        out = loss(make_batch(2, 3, seed=13, tag_key="src"))
        torch.testing.assert_close(out["loss_qvalue"], ref["loss_qvalue"])
        with pytest.raises(KeyError, match='"src"'):
            loss(make_batch(2, 3, seed=13))
        loss.set_keys(is_teacher=None)  # back to the default
        assert loss.tensor_keys.is_teacher == "is_teacher"
        with pytest.raises(ValueError, match="not an accepted tensordict key"):
            loss.set_keys(teacher_tag="x")

    def test_soft_update_works_without_warning(self):
        actor, critic = make_nets()
        loss = SAILLoss(actor, critic, action_spec=SPEC, alpha=0.5)
        loss.make_value_estimator(gamma=GAMMA)
        with pytest.warns(UserWarning, match="No target network updater"):
            loss(make_batch(2, 2))
        actor, critic = make_nets()
        loss = SAILLoss(actor, critic, action_spec=SPEC, alpha=0.5)
        loss.make_value_estimator(gamma=GAMMA)
        updater = SoftUpdate(loss, tau=0.25)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            out = loss(make_batch(2, 2))
            target = loss.target_qvalue_network_params.clone()
            with torch.no_grad():
                for p in q_params(loss):
                    p.add_(1.0)
            updater.step()
        new_target = loss.target_qvalue_network_params
        for key, old in target.items(True, True):
            # target <- (1 - tau) target + tau source, with source = old target + 1 initially
            torch.testing.assert_close(new_target.get(key), old + 0.25)
        assert torch.isfinite(out["loss_qvalue"])

    # ------------------------------------------------------------------ AlphaScheduler


class TestAlphaScheduler:
    def test_scheduler_dynamic_switches_once_at_first_promotion(self):
        loss = make_loss(alpha=0.9)
        sched = AlphaScheduler(loss)
        assert float(loss.alpha) == 0.5  # the scheduler writes its initial value
        for frames in (0, 1000, 5000):
            assert sched.step(frames=frames, num_promoted=0) == 0.5
            assert sched.switched_at_frame is None
        assert float(loss.alpha) == 0.5
        assert sched.step(frames=6000, num_promoted=2) == 0.0
        assert sched.switched_at_frame == 6000 and float(loss.alpha) == 0.0
        for frames in (7000, 10**6):
            assert sched.step(frames=frames, num_promoted=2) == 0.0
        assert sched.switched_at_frame == 6000
        # a custom final value
        other = AlphaScheduler(_Holder(), initial=0.7, final=0.2)
        assert other.step(frames=10, num_promoted=1) == 0.2 and other.switched_at_frame == 10

    def test_scheduler_linear_values(self):
        holder = _Holder()
        sched = AlphaScheduler(holder, mode="linear", initial=0.5, final=0.0, anneal_frames=300_000)
        # alpha(f) = 0.5 - 0.5 * min(f / 3e5, 1)
        expected = {
            0: 0.5,
            60_000: 0.4,
            150_000: 0.25,
            299_999: 0.5 / 300_000,
            300_000: 0.0,
            10**6: 0.0,
        }
        for frames, value in expected.items():
            assert sched.step(frames=frames, num_promoted=frames // 1000) == pytest.approx(value)
            assert holder.alpha == pytest.approx(value)
        assert sched.switched_at_frame is None
        up = AlphaScheduler(_Holder(), mode="linear", initial=0.2, final=0.6, anneal_frames=100)
        assert up.step(frames=25, num_promoted=0) == pytest.approx(0.3)

    def test_scheduler_constant(self):
        loss = make_loss(alpha=0.5)
        sched = AlphaScheduler(loss, mode="constant", initial=0.0)  # SAIL w/o LfD
        assert float(loss.alpha) == 0.0
        assert sched.step(frames=100, num_promoted=5) == 0.0
        keep = AlphaScheduler(_Holder(), mode="constant")  # SAIL w/o adaptation
        assert keep.step(frames=10**6, num_promoted=10) == 0.5 and keep.switched_at_frame is None

    def test_scheduler_state_dict_round_trip(self):
        sched = AlphaScheduler(_Holder())
        sched.step(frames=100, num_promoted=0)
        sched.step(frames=200, num_promoted=1)
        state = sched.state_dict()
        saved = torch.load(_roundtrip(state), weights_only=True)
        holder = _Holder()
        fresh = AlphaScheduler(holder)
        assert holder.alpha == 0.5
        fresh.load_state_dict(saved)
        assert fresh.alpha == 0.0 and holder.alpha == 0.0 and fresh.switched_at_frame == 200
        assert fresh.state_dict() == state
        # the switch is never undone after a restore
        assert fresh.step(frames=300, num_promoted=1) == 0.0 and fresh.switched_at_frame == 200

    @pytest.mark.parametrize(
        "kwargs,match",
        [
            ({"mode": "anneal"}, "mode"),
            ({"initial": 1.5}, "initial"),
            ({"final": -0.1}, "final"),
            ({"mode": "linear"}, "anneal_frames"),
            ({"mode": "linear", "anneal_frames": 0}, "anneal_frames"),
        ],
    )
    def test_scheduler_validation(self, kwargs, match):
        with pytest.raises(ValueError, match=match):
            AlphaScheduler(_Holder(), **kwargs)


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)
