"""The on-policy baselines of ``sail_td3.py``: GAIL (``algo=gail``) and POfD (``algo=pofd``), PPO generators.

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

import copy
import math
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

from torchrl_sail import DiscriminatorLoss, DivergenceCheck, MixedReplayBuffer, observation_normalizer, \
    TRANSITION_KEYS
from utils import crossings, log_metrics, logger_states, make_discriminator, make_env, make_loggers, \
    make_replay, make_reward, make_teacher, new_run, normalized_observation_key, record_evaluation, \
    start_or_resume, train_timing, write_summary
from video import log_video, make_render_env


def make_ppo_models(cfg, env):
    """TorchRL's sota PPO/GAIL networks for MuJoCo: tanh MLPs, a state-independent scale, TanhNormal.

    Both read the normalised observations when the run normalises them (``algo.ppo.normalize_observations``).
    """
    key = normalized_observation_key(cfg) or "observation"
    obs_dim, spec = env.observation_spec[key].shape[-1], env.action_spec
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
        TensorDictModule(policy, in_keys=[key], out_keys=["loc", "scale"]),
        in_keys=["loc", "scale"], spec=spec, distribution_class=TanhNormal,
        distribution_kwargs={"low": spec.space.low, "high": spec.space.high, "tanh_loc": False},
        return_log_prob=True, default_interaction_type=ExplorationType.RANDOM,
    )
    return actor, ValueOperator(value, in_keys=[key])


def copy_observation_norm(source_env, target_env) -> None:
    """Gives ``target_env``'s observation normaliser the statistics of ``source_env``'s, frozen.

    Evaluation and video envs run the training statistics without updating them (a copy: the
    training env's own are never touched by an evaluation). Envs without a normaliser: nothing.
    """
    source, target = observation_normalizer(source_env), observation_normalizer(target_env)
    if target is None:
        return
    target.load_state_dict(copy.deepcopy(source.state_dict()))
    target.freeze()


def pofd_lambda(coef: float, decay: float, iteration: int) -> float:
    """POfD's ``lambda_1`` at the ``iteration``-th on-policy batch (0-based): ``coef * decay ** iteration``.

    A function of the batch index alone, which the frame count gives: a resumed run continues the schedule.
    """
    return coef * decay ** iteration


def lr_factor(updates_done: int, total_updates: int) -> float:
    """TorchRL's PPO annealing: ``1 - updates_done / total_updates``, floored at 0 (a run extended past its budget)."""
    return max(0.0, 1.0 - updates_done / total_updates)


def run_gail(cfg, run_dir: Path, resuming: bool) -> None:
    p, d, r = cfg.algo.ppo, cfg.optim.discriminator, cfg.algo.reward
    env, eval_env = make_env(cfg, cfg.seed), make_env(cfg, cfg.seed + 10_000)
    teacher, teacher_return, teacher_source = make_teacher(cfg, env)
    actor, critic = make_ppo_models(cfg, env)
    discriminator = make_discriminator(cfg, env)
    advantage = GAE(gamma=cfg.optim.gamma, lmbda=p.gae_lambda, value_network=critic, average_gae=False)
    ppo_loss = ClipPPOLoss(actor, critic, clip_epsilon=p.clip_epsilon, entropy_coeff=p.entropy_coef,
                           critic_coeff=p.critic_coef, loss_critic_type=str(p.loss_critic_type),
                           normalize_advantage=True)
    d_loss = DiscriminatorLoss(discriminator, entropy_coef=d.entropy_coef, gp_coef=d.gp_coef)
    optimizers = {"ppo": group_optimizers(torch.optim.Adam(actor.parameters(), lr=p.lr, eps=1e-5),
                                          torch.optim.Adam(critic.parameters(), lr=p.lr, eps=1e-5)),
                  "discriminator": torch.optim.Adam(discriminator.parameters(), lr=d.lr)}
    # gail: -log(1 - D) replaces the env reward; pofd: added to it, times lambda_1 (its coef)
    reward = make_reward(cfg, discriminator)
    shaped = r.source == "shaped"
    on_policy = make_replay(p.frames_per_batch, cfg.device)  # this batch's transitions, for D
    d_batches = MixedReplayBuffer(teacher, on_policy)
    minibatches = TensorDictReplayBuffer(storage=LazyTensorStorage(p.frames_per_batch, device=cfg.device),
                                         sampler=SamplerWithoutReplacement(), batch_size=p.minibatch_size)
    # TorchRL anneals over every PPO update of the budget: batches x epochs x minibatches per epoch
    total_updates = (cfg.collector.total_frames // p.frames_per_batch) * p.epochs * math.ceil(
        p.frames_per_batch / p.minibatch_size)
    observation_norm = observation_normalizer(env)  # None with algo.ppo.normalize_observations=false

    run = new_run(cfg)
    stateful = {"actor": actor, "critic": critic, "discriminator": discriminator, "rng": GlobalRNGState(),
                "run": run, **{f"optim_{name}": optimizer for name, optimizer in optimizers.items()}}
    if observation_norm is not None:  # the policy's input statistics: a resumed run goes on with them
        stateful["observation_norm"] = observation_norm
    checkpoint = Checkpoint(**stateful)
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
        metrics["sail/env_reward_mean"] = data["next", "reward"].mean()
        on_policy.empty()
        # raw observations (not the policy's normalised ones): D compares them with the teacher's
        on_policy.extend(data.reshape(-1).select(*TRANSITION_KEYS))
        # D: one pass over the batch's rows, each step against as many teacher rows
        for batch in d_batches.sample(2 * d.batch_size, teacher_fraction=0.5,
                                      num_batches=max(1, data.numel() // d.batch_size)).unbind(0):
            out = d_loss(batch)
            sum(value for key, value in out.items() if key.startswith("loss_")).backward()
            optimizers["discriminator"].step()
            optimizers["discriminator"].zero_grad(set_to_none=True)
            metrics.update({f"d/{key}": value for key, value in out.items()})
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
        check(metrics, frames)  # NaN/inf stops the run before it is evaluated, logged or saved

        if crossings(cfg.eval.every_frames, 0, before, frames):
            copy_observation_norm(env, eval_env)
            metrics["eval/return"] = record_evaluation(eval_env, actor, cfg, run, frames, teacher_return)
        if crossings(cfg.eval.video_every_frames, 0, before, frames):
            copy_observation_norm(env, render_env)
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
