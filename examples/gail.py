"""The on-policy baselines: GAIL (``algo=gail``) and POfD (``algo=pofd``), PPO generators learning
from the delayed reward and one teacher demonstration, in TorchRL.

    python examples/gail.py algo=gail env=Hopper-v4 teacher.path=<teacher.npz|dataset folder>
    python examples/gail.py algo=pofd env=Hopper-v4 teacher.path=...

The same config (``conf/config.yaml``), overrides and run folder as ``sail_td3.py``, which runs
the off-policy methods; ``algo=`` must name an on-policy method (``algo.learner=ppo``).

Per collected batch, as TorchRL's sota GAIL script does: the discriminator takes one pass over
the batch against teacher rows (SAIL's ``Discriminator`` and ``DiscriminatorLoss``), the batch
is rewarded by the updated discriminator, and TorchRL's ``ClipPPOLoss`` trains the actor and the
value network for a few epochs on GAE advantages. The reward (``algo.reward``, built by
``make_reward``):

- GAIL (Ho and Ermon 2016): ``-log(1 - D)`` replaces the delayed env reward;
- POfD (Kang, Jie and Feng 2018): the delayed env reward shaped by the occupancy-measure matching
  term, ``r_env + lambda_1 * -log(1 - D)`` (the paper's ``r - lambda_1 log D_w`` with ``D_w`` the
  probability of the policy), ``lambda_1 = algo.reward.coef * algo.reward.coef_decay ** i`` at
  the i-th batch (:func:`pofd_lambda`).

The PPO settings are TorchRL's PPO MuJoCo example's (``sota-implementations/ppo``, which its GAIL
example shares): the actor and the critic read observations normalised by TorchRL's ``VecNormV2``
and clipped to [-10, 10] (``make_sail_env(normalized_observation_key=...)``; the discriminator
reads the raw ones, as the teacher's are), the learning rate decays linearly to 0 over the run's
PPO updates, L2 critic loss weighted 0.25, Adam eps 1e-5, no gradient clipping. The training env's
normaliser statistics are saved in the checkpoint (restored on resume) and copied, frozen, into
the evaluation and video envs. The run folder holds the same files as the other methods'.
"""

from __future__ import annotations

from mujoco_gl import check_mujoco_gl

check_mujoco_gl()  # before TorchRL imports MuJoCo, which loads the MUJOCO_GL backend on import

import math

import hydra
import torch
import tqdm
from config_schema import register_config_schema
from run_utils import (
    EXAMPLES_DIR,
    RunCheckpoint,
    RunClock,
    crossings,
    log_metrics,
    make_loggers,
    make_run,
    record_evaluation,
    start_run,
    write_run_summary,
)
from torchrl.checkpoint import Checkpoint, GlobalRNGState
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, SamplerWithoutReplacement, TensorDictReplayBuffer
from torchrl.objectives import ClipPPOLoss, group_optimizers
from torchrl.objectives.value import GAE
from utils import (
    copy_observation_norm,
    discriminator_block,
    make_discriminator,
    make_discriminator_loss,
    make_env,
    make_eval_env,
    make_ppo_models,
    make_replay,
    make_reward,
    make_teacher,
)
from video import log_video, make_render_env

from torchrl_sail import TRANSITION_KEYS, DivergenceCheck, MixedReplayBuffer, observation_normalizer
from torchrl_sail.harness import start_or_resume

register_config_schema()  # the typed schema conf/config.yaml extends: Hydra checks every value against it


def pofd_lambda(coef: float, decay: float, iteration: int) -> float:
    """POfD's ``lambda_1`` at the ``iteration``-th on-policy batch (0-based): ``coef * decay ** iteration``.

    A function of the batch index alone, which the frame count gives: a resumed run continues the schedule.
    """
    return coef * decay**iteration


def ppo_updates(total_frames: int, frames_per_batch: int, epochs: int, minibatch_size: int) -> int:
    """Every PPO update of the budget, over which TorchRL anneals: batches x epochs x minibatches per
    epoch. TorchRL's ``Collector`` rounds the budget up to whole batches, and so does the count:
    the last batch trains at a learning rate above 0."""
    return math.ceil(total_frames / frames_per_batch) * epochs * math.ceil(frames_per_batch / minibatch_size)


def lr_factor(updates_done: int, total_updates: int) -> float:
    """TorchRL's PPO annealing: ``1 - updates_done / total_updates``, floored at 0 (a run extended past its budget)."""
    return max(0.0, 1.0 - updates_done / total_updates)


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
def main(cfg):  # noqa: F821
    run_dir, resuming = start_run(cfg, "gail.py")  # the off-policy methods: sail_td3.py; algo=bc: bc.py
    if resuming is None:
        return

    p, d, r = cfg.algo.ppo, cfg.optim.discriminator, cfg.algo.reward
    env, eval_env = make_env(cfg, cfg.seed), make_eval_env(cfg, cfg.seed + 10_000, cfg.eval.episodes)
    teacher, teacher_return, teacher_source = make_teacher(cfg, env)
    actor, critic = make_ppo_models(cfg, env)
    discriminator = make_discriminator(cfg, env)
    advantage = GAE(gamma=cfg.optim.gamma, lmbda=p.gae_lambda, value_network=critic, average_gae=False)
    ppo_loss = ClipPPOLoss(
        actor,
        critic,
        clip_epsilon=p.clip_epsilon,
        entropy_coeff=p.entropy_coef,
        critic_coeff=p.critic_coef,
        loss_critic_type=str(p.loss_critic_type),
        normalize_advantage=True,
    )
    d_loss = make_discriminator_loss(cfg, discriminator)
    optimizers = {
        "ppo": group_optimizers(
            torch.optim.Adam(actor.parameters(), lr=p.lr, eps=1e-5),
            torch.optim.Adam(critic.parameters(), lr=p.lr, eps=1e-5),
        ),
        "discriminator": torch.optim.Adam(discriminator.parameters(), lr=d.lr),
    }
    # gail: -log(1 - D) replaces the env reward; pofd: added to it, times lambda_1 (its coef)
    reward = make_reward(cfg, discriminator)
    shaped = r.source == "shaped"
    on_policy = make_replay(p.frames_per_batch, cfg.device)  # this batch's transitions, for D
    d_batches = MixedReplayBuffer(teacher, on_policy)
    minibatches = TensorDictReplayBuffer(
        storage=LazyTensorStorage(p.frames_per_batch, device=cfg.device),
        sampler=SamplerWithoutReplacement(),
        batch_size=p.minibatch_size,
    )
    total_updates = ppo_updates(cfg.collector.total_frames, p.frames_per_batch, p.epochs, p.minibatch_size)
    observation_norm = observation_normalizer(env)  # None with algo.ppo.normalize_observations=false

    run = make_run(cfg)
    stateful = {
        "actor": actor,
        "critic": critic,
        "discriminator": discriminator,
        "rng": GlobalRNGState(),
        "run": run,
        **{f"optim_{name}": optimizer for name, optimizer in optimizers.items()},
    }
    if observation_norm is not None:  # the policy's input statistics: a resumed run goes on with them
        stateful["observation_norm"] = observation_norm
    checkpoint = Checkpoint(**stateful)
    start_or_resume(
        checkpoint, run_dir, run, resuming, optimizers=optimizers.values(), config=cfg, code_dir=EXAMPLES_DIR
    )
    if resuming:
        env.set_seed(cfg.seed + run["frames"])  # a different episode stream than the one before the stop
    loggers = make_loggers(cfg, run_dir, run["loggers"])
    divergence = DivergenceCheck({"actor": actor, "critic": critic, "discriminator": discriminator})

    render_env = make_render_env(cfg, cfg.seed + 30_000, cfg.eval.video_size) if cfg.eval.video_every_frames else None
    frames, metrics = run["frames"], {}
    collector = Collector(
        env,
        actor,
        frames_per_batch=p.frames_per_batch,
        track_traj_ids=False,
        total_frames=max(cfg.collector.total_frames - frames, 0),
    )
    pbar = tqdm.tqdm(total=cfg.collector.total_frames, initial=frames, unit="frames")
    clock = RunClock(run, frames)  # no warm-up: the whole run is timed
    save = RunCheckpoint(checkpoint, run_dir, run, loggers=loggers, divergence=divergence, clock=clock)
    for data in clock.batches(collector, frames):
        before, frames = frames, frames + data.numel()
        metrics = {}
        done = data["next", "done"].reshape(-1)
        if done.any():  # before D's reward replaces the env's
            metrics["train/dense_return"] = data["next", "episode_return"].reshape(-1)[done].mean()
            metrics["train/delayed_reward"] = data["next", "reward"].reshape(-1)[done].mean()
        metrics["sail/env_reward_mean"] = data["next", "reward"].mean()
        on_policy.empty()
        # raw observations (not the policy's normalised ones): D compares them with the teacher's
        on_policy.extend(data.reshape(-1).select(*TRANSITION_KEYS))
        # D: optim.discriminator.steps steps per batch, each on batch_size of its rows and as many teacher rows
        d_block = d_batches.sample(2 * d.batch_size, teacher_fraction=0.5, num_batches=d.steps)
        metrics.update(discriminator_block(cfg, d_loss, optimizers["discriminator"], d_block))
        if shaped:
            reward.coef = metrics["pofd/lambda_1"] = pofd_lambda(r.coef, r.coef_decay, before // p.frames_per_batch)
        data = reward(data)  # the updated D's reward (gail: replaces the delayed env reward; pofd: shapes it)
        metrics["sail/d_reward_mean"] = data["next", "reward"].mean()
        for _ in range(p.epochs):
            with torch.no_grad():
                data = advantage(data)
            minibatches.empty()
            minibatches.extend(data.reshape(-1))
            for batch in minibatches:
                factor = lr_factor(run["gradient_steps"], total_updates) if p.anneal_lr else 1.0
                for group in optimizers["ppo"].param_groups:
                    group["lr"] = p.lr * factor
                if p.anneal_clip_epsilon:
                    ppo_loss.clip_epsilon.copy_(p.clip_epsilon * factor)
                out = ppo_loss(batch)
                (out["loss_objective"] + out["loss_entropy"] + out["loss_critic"]).backward()
                optimizers["ppo"].step()
                optimizers["ppo"].zero_grad(set_to_none=True)
                run["gradient_steps"] += 1
        metrics.update({f"ppo/{key}": out[key].detach() for key in ("loss_objective", "loss_critic", "entropy")})
        metrics["ppo/lr"] = p.lr * factor  # of the batch's last update
        save.check(metrics, frames)  # NaN/inf stops the run before it is evaluated, logged or saved

        if crossings(cfg.eval.every_frames, 0, before, frames):
            copy_observation_norm(env, eval_env)
            metrics.update(record_evaluation(eval_env, actor, None, cfg, run, frames, teacher_return))
        if crossings(cfg.eval.video_every_frames, 0, before, frames):
            copy_observation_norm(env, render_env)
            log_video(loggers, render_env, actor, cfg, run_dir, frames)
        metrics["time/fps"] = clock.fps(frames)
        log_metrics(loggers, metrics, frames)
        pbar.update(data.numel())
        if crossings(cfg.checkpoint.every_frames, 0, before, frames):
            save(metrics, frames=frames)
    collector.shutdown()
    pbar.close()
    clock.stop()
    save(metrics, frames=frames)
    write_run_summary(
        run_dir, cfg, run, teacher_return=teacher_return, teacher_source=teacher_source, clock=clock, num_promoted=0
    )


if __name__ == "__main__":
    main()
