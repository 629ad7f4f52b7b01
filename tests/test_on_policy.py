"""The on-policy baselines' pieces (examples/gail.py and its builders in examples/utils.py): observation
normalisation, its checkpoint and its freezing at evaluation, what the discriminator reads, POfD's lambda_1
and PPO's lr schedules."""

from __future__ import annotations

import copy
import sys
from pathlib import Path

import pytest
import torch
from hydra import compose, initialize_config_dir
from torchrl.checkpoint import Checkpoint

from torchrl_sail import make_sail_env, observation_normalizer

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "examples"))
from config_schema import register_config_schema  # noqa: E402
from gail import lr_factor, pofd_lambda, ppo_updates  # noqa: E402
from run_utils import evaluate_episodes  # noqa: E402
from utils import copy_observation_norm, make_discriminator, make_env, make_ppo_models  # noqa: E402

register_config_schema()


def make_cfg(*overrides: str):
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base="1.3"):
        return compose(config_name="config", overrides=["env=Hopper-v4", *overrides])


def stats(norm) -> dict:
    """A normaliser's statistics, copied (loc, var, count)."""
    return copy.deepcopy(norm.state_dict()["_extra_state"])


def assert_same_stats(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for key in a:
        assert torch.equal(a[key], b[key]), key


def rollout(env, steps: int, seed: int = 0):
    env.set_seed(seed)
    torch.manual_seed(seed)  # the random actions of rollout(policy=None)
    return env.rollout(steps, break_when_any_done=False)


def test_policy_reads_normalised_observations_and_d_the_raw_ones():
    cfg = make_cfg("algo=gail")
    env = make_env(cfg, 0)
    actor, critic = make_ppo_models(cfg, env)
    assert actor.in_keys == ["observation_norm"] and critic.in_keys == ["observation_norm"]
    assert make_discriminator(cfg, env).in_keys == ["observation", "action"]  # the teacher's layout
    # The same seed and actions on the plain SAIL env: "observation" is exactly the raw one
    normalised, plain = rollout(env, 30), rollout(make_sail_env("Hopper-v4"), 30)
    assert torch.equal(normalised["observation"], plain["observation"])
    assert torch.equal(normalised["next", "observation"], plain["next", "observation"])
    # The policy's copy: (raw - loc) / scale of the normaliser's statistics (the last step was
    # normalised after its own update, i.e. with the final statistics), clipped to [-10, 10]; the
    # time feature appended raw
    norm = observation_normalizer(env)
    loc, scale = norm.loc["observation"], norm.scale["observation"]
    raw = plain["next", "observation"][-1]
    expected = ((raw[:-1].double() - loc) / scale).clamp(-10, 10).float()
    torch.testing.assert_close(normalised["next", "observation_norm"][-1, :-1], expected, rtol=0, atol=1e-4)
    assert torch.equal(normalised["next", "observation_norm"][..., -1], plain["next", "observation"][..., -1])
    # one update per reset (the first, and one after each episode that ended before the last step) and step
    resets = 1 + int(normalised["next", "done"][:-1].sum())
    assert resets >= 2 and int(stats(norm)["count.-|-.observation"]) == resets + 30
    # Runs without normalisation (and runs saved before it) keep one raw observation
    plain_cfg = make_cfg("algo=gail", "algo.ppo.normalize_observations=false")
    assert make_ppo_models(plain_cfg, make_env(plain_cfg, 0))[0].in_keys == ["observation"]


@pytest.mark.parametrize("episodes", [1, 3])
def test_evaluation_runs_the_training_statistics_frozen(episodes):
    """On one env and on a batched env of 3 (eval.vectorized), evaluations normalise with the
    training statistics, frozen."""
    cfg = make_cfg("algo=gail")
    train_env, eval_env = make_env(cfg, 0), make_env(cfg, 10_000, num_envs=episodes)
    rollout(train_env, 40)
    trained = stats(observation_normalizer(train_env))
    copy_observation_norm(train_env, eval_env)
    eval_norm = observation_normalizer(eval_env)
    assert eval_norm.frozen and not observation_normalizer(train_env).frozen
    assert_same_stats(stats(eval_norm), trained)
    actor, _ = make_ppo_models(cfg, train_env)
    played = evaluate_episodes(eval_env, actor, episodes, 50, keep_rollouts=True)
    # An evaluation changes neither the training statistics nor its frozen copy ...
    assert_same_stats(stats(observation_normalizer(train_env)), trained)
    assert_same_stats(stats(eval_norm), trained)
    # ... and normalises with the training statistics
    train_norm = observation_normalizer(train_env)
    loc, scale = train_norm.loc["observation"], train_norm.scale["observation"]
    for episode in (e["rollout"] for e in played):
        expected = ((episode["next", "observation"][:, :-1].double() - loc) / scale).clamp(-10, 10).float()
        torch.testing.assert_close(episode["next", "observation_norm"][:, :-1], expected, rtol=0, atol=1e-4)
    # the copy is the statistics, not a view of them: training goes on without moving the frozen copy
    rollout(train_env, 5, seed=1)
    assert_same_stats(stats(eval_norm), trained)


def test_checkpoint_restores_the_statistics(tmp_path):
    cfg = make_cfg("algo=gail")
    env = make_env(cfg, 0)
    rollout(env, 25)
    Checkpoint(observation_norm=observation_normalizer(env)).save(tmp_path / "checkpoint")
    fresh = make_env(cfg, 1)
    assert int(stats(observation_normalizer(fresh))["count.-|-.observation"]) == 0
    Checkpoint(observation_norm=observation_normalizer(fresh)).load(tmp_path / "checkpoint")
    assert_same_stats(stats(observation_normalizer(fresh)), stats(observation_normalizer(env)))
    assert int(stats(observation_normalizer(fresh))["count.-|-.observation"]) >= 26  # 25 steps and the resets
    torch.testing.assert_close(
        observation_normalizer(fresh).scale["observation"],
        observation_normalizer(env).scale["observation"],
        rtol=0,
        atol=0,
    )


def test_pofd_lambda_and_lr_schedules():
    # lambda_1 = coef * decay ** i at the i-th batch (0-based)
    assert [pofd_lambda(0.1, 0.5, i) for i in range(4)] == [0.1, 0.05, 0.025, 0.0125]
    assert pofd_lambda(0.1, 0.99, 100) == pytest.approx(0.036603234, rel=1e-8)  # 0.1 * 0.99^100
    cfg = make_cfg("algo=pofd")
    r = cfg.algo.reward
    # the one public reimplementation's constant lambda_1 (no schedule found for the paper)
    assert (r.source, r.kind, r.coef, r.coef_decay, cfg.algo.learner) == ("shaped", "gail", 0.1, 1.0, "ppo")
    # the last of 1M frames' 489 batches of 2048 (the Collector rounds the budget up): still 0.1
    assert pofd_lambda(r.coef, r.coef_decay, 488) == 0.1 and -(-1_000_000 // 2048) == 489
    # TorchRL's PPO lr: 1 - done / all updates, floored at 0
    # a 300k budget is 147 batches of 2048 (TorchRL's Collector rounds 146.48 up), 32 minibatches of 64
    assert ppo_updates(300_000, 2048, 10, 64) == 147 * 10 * 32 and ppo_updates(2048, 512, 10, 64) == 320
    assert lr_factor(147 * 320 - 1, ppo_updates(300_000, 2048, 10, 64)) > 0  # the last update's
    assert lr_factor(0, 320) == 1.0 and lr_factor(319, 320) == pytest.approx(1 / 320) and lr_factor(400, 320) == 0.0
    gail = make_cfg("algo=gail").algo.ppo
    assert (
        gail.critic_coef,
        gail.loss_critic_type,
        gail.anneal_lr,
        gail.anneal_clip_epsilon,
        gail.normalize_observations,
    ) == (0.25, "l2", True, False, True)
