"""GAIL with a PPO generator, the ``algo=gail`` baseline of ``sail_td3.py`` (on-policy).

Per collected batch, as TorchRL's sota GAIL script does: the discriminator takes one pass over
the batch against teacher rows (SAIL's ``Discriminator`` and ``DiscriminatorLoss``), the batch
is rewarded with ``-log(1 - D)`` by the updated discriminator, and TorchRL's ``ClipPPOLoss``
trains the actor and the value network for a few epochs on GAE advantages. The run folder
holds the same files as the other methods'.
"""
from __future__ import annotations

import time
from pathlib import Path

import torch
import tqdm
from tensordict.nn import AddStateIndependentNormalScale, TensorDictModule
from torch import nn
from torchrl.checkpoint import Checkpoint, GlobalRNGState
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, SamplerWithoutReplacement, TensorDictReplayBuffer
from torchrl.envs import ExplorationType
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import ClipPPOLoss, group_optimizers
from torchrl.objectives.value import GAE

from torchrl_sail import DiscriminatorLoss, DivergenceCheck, DiscriminatorReward, MixedReplayBuffer, TRANSITION_KEYS
from utils import crossings, log_metrics, logger_states, make_discriminator, make_env, make_loggers, \
    make_replay, make_teacher, new_run, record_evaluation, start_or_resume, train_timing, write_summary
from video import log_video, make_render_env


def make_ppo_models(cfg, env):
    """TorchRL's sota PPO/GAIL networks for MuJoCo: tanh MLPs, a state-independent scale, TanhNormal."""
    obs_dim, spec = env.observation_spec["observation"].shape[-1], env.action_spec
    policy = nn.Sequential(
        MLP(in_features=obs_dim, out_features=spec.shape[-1], num_cells=list(cfg.algo.ppo.cells),
            activation_class=nn.Tanh, device=cfg.device),
        AddStateIndependentNormalScale(spec.shape[-1], scale_lb=1e-8, device=cfg.device),
    )
    value = MLP(in_features=obs_dim, out_features=1, num_cells=list(cfg.algo.ppo.cells), activation_class=nn.Tanh,
                device=cfg.device)
    for net, gain in ((policy[0], 1.0), (value, 0.01)):
        for layer in net.modules():
            if isinstance(layer, nn.Linear):
                nn.init.orthogonal_(layer.weight, gain)
                layer.bias.data.zero_()
    actor = ProbabilisticActor(
        TensorDictModule(policy, in_keys=["observation"], out_keys=["loc", "scale"]),
        in_keys=["loc", "scale"], spec=spec, distribution_class=TanhNormal,
        distribution_kwargs={"low": spec.space.low, "high": spec.space.high, "tanh_loc": False},
        return_log_prob=True, default_interaction_type=ExplorationType.RANDOM,
    )
    return actor, ValueOperator(value, in_keys=["observation"])


def run_gail(cfg, run_dir: Path, resuming: bool) -> None:
    p, d = cfg.algo.ppo, cfg.optim.discriminator
    env, eval_env = make_env(cfg, cfg.seed), make_env(cfg, cfg.seed + 10_000)
    teacher, teacher_return, teacher_source = make_teacher(cfg, env)
    actor, critic = make_ppo_models(cfg, env)
    discriminator = make_discriminator(cfg, env)
    advantage = GAE(gamma=cfg.optim.gamma, lmbda=p.gae_lambda, value_network=critic, average_gae=False)
    ppo_loss = ClipPPOLoss(actor, critic, clip_epsilon=p.clip_epsilon, entropy_coeff=p.entropy_coef,
                           critic_coeff=p.critic_coef, normalize_advantage=True)
    d_loss = DiscriminatorLoss(discriminator, entropy_coef=d.entropy_coef, gp_coef=d.gp_coef)
    optimizers = {"ppo": group_optimizers(torch.optim.Adam(actor.parameters(), lr=p.lr, eps=1e-5),
                                          torch.optim.Adam(critic.parameters(), lr=p.lr, eps=1e-5)),
                  "discriminator": torch.optim.Adam(discriminator.parameters(), lr=d.lr)}
    reward = DiscriminatorReward(discriminator)
    on_policy = make_replay(p.frames_per_batch, cfg.device)  # this batch's transitions, for D
    d_batches = MixedReplayBuffer(teacher, on_policy)
    minibatches = TensorDictReplayBuffer(storage=LazyTensorStorage(p.frames_per_batch, device=cfg.device),
                                         sampler=SamplerWithoutReplacement(), batch_size=p.minibatch_size)

    run = new_run(cfg)
    checkpoint = Checkpoint(actor=actor, critic=critic, discriminator=discriminator, rng=GlobalRNGState(), run=run,
                            **{f"optim_{name}": optimizer for name, optimizer in optimizers.items()})
    start_or_resume(checkpoint, run_dir, cfg, run, resuming, optimizers=optimizers.values())
    if resuming:
        env.set_seed(cfg.seed + run["frames"])  # a different episode stream than the one before the stop
    loggers = make_loggers(cfg, run_dir, run["loggers"])
    divergence = DivergenceCheck({"actor": actor, "critic": critic, "discriminator": discriminator})
    checkpoint_path = run_dir / "checkpoint"

    def check(metrics: dict, frames: int) -> None:
        saved = (checkpoint_path / "manifest.json").exists()
        divergence(metrics, frame=frames, checkpoint=f"{checkpoint_path}, frame {run['frames']}" if saved else None)

    def save(frames: int) -> None:
        check(metrics, frames)
        run.update(frames=frames, loggers=logger_states(loggers))
        checkpoint.save(checkpoint_path)

    render_env = make_render_env(cfg, cfg.seed + 30_000, cfg.eval.video_size) if cfg.eval.video_every_frames else None
    frames, metrics = run["frames"], {}
    collector = Collector(env, actor, frames_per_batch=p.frames_per_batch, track_traj_ids=False,
                          total_frames=max(cfg.collector.total_frames - frames, 0))
    pbar = tqdm.tqdm(total=cfg.collector.total_frames, initial=frames, unit="frames")
    start, start_frames, clock = time.time(), frames, (time.time(), frames)
    for data in collector if collector.total_frames else ():
        before, frames = frames, frames + data.numel()
        metrics = {}
        done = data["next", "done"].reshape(-1)
        if done.any():  # before D's reward replaces the env's
            metrics["train/dense_return"] = data["next", "episode_return"].reshape(-1)[done].mean()
            metrics["train/delayed_reward"] = data["next", "reward"].reshape(-1)[done].mean()
        on_policy.empty()
        on_policy.extend(data.reshape(-1).select(*TRANSITION_KEYS))
        # D: one pass over the batch's rows, each step against as many teacher rows
        for batch in d_batches.sample(2 * d.batch_size, teacher_fraction=0.5,
                                      num_batches=max(1, data.numel() // d.batch_size)).unbind(0):
            out = d_loss(batch)
            sum(value for key, value in out.items() if key.startswith("loss_")).backward()
            optimizers["discriminator"].step()
            optimizers["discriminator"].zero_grad(set_to_none=True)
            metrics.update({f"d/{key}": value for key, value in out.items()})
        data = reward(data)  # -log(1 - D) of the updated D replaces the delayed env reward
        metrics["sail/d_reward_mean"] = data["next", "reward"].mean()
        for _ in range(p.epochs):
            with torch.no_grad():
                data = advantage(data)
            minibatches.empty()
            minibatches.extend(data.reshape(-1))
            for batch in minibatches:
                out = ppo_loss(batch)
                (out["loss_objective"] + out["loss_entropy"] + out["loss_critic"]).backward()
                optimizers["ppo"].step()
                optimizers["ppo"].zero_grad(set_to_none=True)
                run["gradient_steps"] += 1
        metrics.update({f"ppo/{key}": out[key].detach() for key in ("loss_objective", "loss_critic", "entropy")})
        check(metrics, frames)  # NaN/inf stops the run before it is evaluated, logged or saved

        if crossings(cfg.eval.every_frames, 0, before, frames):
            metrics["eval/return"] = record_evaluation(eval_env, actor, cfg, run, frames, teacher_return)
        if crossings(cfg.eval.video_every_frames, 0, before, frames):
            log_video(loggers, render_env, actor, cfg, run_dir, frames)
        metrics["time/fps"] = (frames - start_frames) / max(time.time() - start, 1e-9)
        log_metrics(loggers, metrics, frames)
        pbar.update(data.numel())
        if crossings(cfg.checkpoint.every_frames, 0, before, frames):
            save(frames)
    collector.shutdown()
    pbar.close()
    end = time.time()
    save(frames)
    evals = [value for _, value in run["evals"]]
    write_summary(
        run_dir, cfg, teacher_return=teacher_return, alpha_switch_frame=None, teacher_source=teacher_source,
        frames=frames, gradient_steps=run["gradient_steps"], final_eval_return=evals[-1] if evals else None,
        best_eval_return=max(evals) if evals else None, passed_teacher_at_frame=run["passed_teacher_at"],
        num_promoted=0, frames_per_second=(frames - start_frames) / max(end - start, 1e-9),
        **train_timing(clock, end=end, frames=frames),
    )
