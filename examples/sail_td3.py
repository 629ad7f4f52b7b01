"""SAIL (Self-Adaptive Imitation Learning) on MuJoCo with TorchRL: TD3 + discriminator
reward + an adaptive top-K teacher buffer, learning from one delayed reward per episode.

    python examples/sail_td3.py env=Walker2d-v4
    python examples/sail_td3.py env=Hopper-v4 teacher.path=<teachers>/<the paper's Hopper file>.npz
    python examples/sail_td3.py -m seed=0,1,2            # Hydra multirun
    python examples/sail_td3.py algo=dac                 # every off-policy method (algo.learner=td3 or sac)

This script runs the off-policy methods: SAIL and its ablations, dac, dac_published,
td3_delayed, ddpgfd, pofd_td3 (``conf/algo/``). The on-policy ones (gail, pofd) are
``examples/gail.py``, behaviour cloning is ``examples/bc.py``: same config, same run folder.

The default cadence is the authors' code: 10k random warm-up frames, then every 1000
frames 1000 TD3 steps on batches of 256 rows and every 500 frames 10 discriminator steps
of 256 teacher + 256 agent rows. alpha (0.5, dropped to 0 at the first promoted
trajectory) takes effect through the batch composition: a TD3 batch holds
round(alpha * 256) teacher rows and SAILLoss(mixing="batch") weighs every row alike.
Each run writes to its folder (``hydra.run.dir``): the resolved config, TorchRL logger
outputs (``logs/``), ``learning_curve.png``, ``summary.json`` and ``checkpoint/``
(``resume=true`` continues from it).
"""

from __future__ import annotations

from mujoco_gl import check_mujoco_gl

check_mujoco_gl()  # before TorchRL imports MuJoCo, which loads the MUJOCO_GL backend on import

import time

import hydra
import torch
import tqdm
from config_schema import register_config_schema
from run_utils import (
    EXAMPLES_DIR,
    BestPolicy,
    actor_lr,
    crossings,
    evaluate,
    evaluate_actor,
    log_metrics,
    logger_states,
    make_loggers,
    make_run,
    record_evaluation,
    start_run,
    write_run_summary,
)
from torchrl.checkpoint import Checkpoint, GlobalRNGState
from utils import (
    ActorDrift,
    FilledRows,
    actor_saturation,
    discriminator_block,
    make_absorbing,
    make_agent,
    make_collector,
    make_discriminator,
    make_env,
    make_losses,
    make_nstep,
    make_optimizers,
    make_replay,
    make_reward,
    make_rnd,
    make_teacher,
    make_update,
    stored_keys,
)
from video import log_video, make_render_env

from torchrl_sail import TRANSITION_KEYS, DivergenceCheck, MixedReplayBuffer
from torchrl_sail._compat import timeit
from torchrl_sail.runs import (
    BEST_POLICY,
    checkpoint_dir,
    fall_share,
    last_checkpoint,
    start_or_resume,
    train_timing,
    wall_time,
)

register_config_schema()  # the typed schema conf/config.yaml extends: Hydra checks every value against it


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
def main(cfg):  # noqa: F821
    run_dir, resuming = start_run(cfg, "sail_td3.py")  # algo=gail, pofd: gail.py; algo=bc: bc.py
    if resuming is None:
        return

    # --- env, teacher, buffers (everything is validated before training starts)
    env, eval_env = make_env(cfg, cfg.seed), make_env(cfg, cfg.seed + 10_000)
    # eval.other_actor: the other actor's episodes start where the evaluated one's do (same seed, own env)
    other_eval_env = make_env(cfg, cfg.seed + 10_000) if cfg.eval.other_actor else None
    other_actor = "online" if cfg.eval.actor == "target" else "target"
    # SAIL-RND: a curiosity bonus whose statistics the training env keeps (None for other methods)
    rnd, rnd_loss = make_rnd(cfg, env)
    # DAC: terminal transitions go into an absorbing state (the env appends its indicator); the
    # demonstrations' absorbing transitions store the zero action, the agent's algo.absorbing_action
    absorbing = make_absorbing(cfg, env.action_spec)
    teacher, teacher_return, teacher_source = make_teacher(cfg, env, make_absorbing(cfg))
    replay = make_replay(cfg.env.replay_size, cfg.device)
    # DDPGfD: each agent transition is stored with its n-step view (None for the other methods)
    nstep = make_nstep(cfg)
    # SAIL-OnPolicy trains D against the most recent transitions only.
    recent = (
        make_replay(cfg.algo.recent_window, cfg.device) if cfg.algo.discriminator_agent_data == "recent" else replay
    )

    # --- networks, losses, optimizers, batches
    actor, critic, exploration_policy = make_agent(cfg, env)
    discriminator = make_discriminator(cfg, env)
    loss, target_updater, alpha_scheduler, d_loss = make_losses(cfg, actor, critic, discriminator, env.action_spec)
    optimizers = make_optimizers(cfg, loss, discriminator, rnd)
    # TD3 batches get the reward of the *current* D (and RND predictor) at sample time
    # (reward.source=env: the env's alone), D once per distinct stored row of a block.
    reward = make_reward(cfg, discriminator, rnd, row_id_key="row_id")
    uses_discriminator = cfg.algo.reward.source != "env"
    sail_batches = MixedReplayBuffer(teacher, replay, transform=reward, row_id_key="row_id", keys=stored_keys(cfg))
    d_batches = MixedReplayBuffer(teacher, recent)

    # the authors' best policy: the actor at the best mean of the last training returns
    best_policy = BestPolicy(loss, every_frames=cfg.eval.best_policy.every_frames, window=cfg.eval.best_policy.window)
    # how far each TD3 block moves the actor (TD3 learners)
    drift = ActorDrift(actor, loss) if cfg.algo.learner == "td3" else None

    # --- everything a stopped run needs to continue, saved and restored as one
    run = make_run(cfg)
    stateful = {
        "loss": loss,
        "discriminator": discriminator,
        "replay": FilledRows(replay),
        "teacher": teacher,
        "alpha": alpha_scheduler,
        "rng": GlobalRNGState(),
        "run": run,
        "best_policy": best_policy,
        **{f"optim_{name}": optimizer for name, optimizer in optimizers.items()},
    }
    if recent is not replay:
        stateful["recent"] = FilledRows(recent)
    if rnd is not None:
        stateful["rnd"] = rnd
    checkpoint = Checkpoint(**stateful)
    start_or_resume(
        checkpoint, run_dir, run, resuming, optimizers=optimizers.values(), config=cfg, code_dir=EXAMPLES_DIR
    )
    if resuming:
        # The env restarts on a fresh episode: a trajectory cut by the stop is not offered.
        teacher.writer.clear_unfinished()
        env.set_seed(cfg.seed + run["frames"])  # a different episode stream than the one before the stop
    loggers = make_loggers(cfg, run_dir, run["loggers"])
    # NaN/inf in a logged loss or a parameter stops the run before it is logged or saved
    divergence = DivergenceCheck({"loss": loss, "discriminator": discriminator, **({"rnd": rnd} if rnd else {})})

    # Videos of one deterministic episode (eval.video_every_frames; a missing GL backend fails here, before training)
    render_env = make_render_env(cfg, cfg.seed + 30_000, cfg.eval.video_size) if cfg.eval.video_every_frames else None

    update = make_update(cfg, loss, optimizers, target_updater)
    reduced_precision = torch.autocast(
        torch.device(cfg.device).type, dtype=torch.bfloat16, enabled=cfg.optim.precision == "bf16"
    )

    def rnd_update(batch) -> dict:
        rnd_loss.obs_rms = rnd.obs_rms  # the env's running statistics, created at its first step
        out = rnd_loss(batch[~batch["is_teacher"]])  # the predictor learns the agent's states
        out["loss_predictor"].backward()
        optimizers["rnd"].step()
        optimizers["rnd"].zero_grad(set_to_none=True)
        return {"rnd/loss_predictor": out["loss_predictor"].detach()}

    def save(frames: int, gradient_steps: int) -> None:
        divergence(metrics, frame=frames, checkpoint=last_checkpoint(run_dir, run))
        wall_seconds = wall_time(wall_before, start, time.time())
        run.update(
            frames=frames, gradient_steps=gradient_steps, loggers=logger_states(loggers), wall_seconds=wall_seconds
        )
        checkpoint.save(checkpoint_dir(run_dir))
        best_policy.write(run_dir / BEST_POLICY)  # after the checkpoint it matches

    o, d, warmup = cfg.optim, cfg.optim.discriminator, cfg.collector.init_random_frames
    frames, gradient_steps = run["frames"], run["gradient_steps"]
    collector = make_collector(cfg, env, exploration_policy, frames=frames)
    pbar = tqdm.tqdm(total=cfg.collector.total_frames, initial=frames, unit="frames")
    start, start_frames, last_log, metrics = time.time(), frames, frames, {}
    wall_before = run["wall_seconds"]  # the wall time of the run's earlier starts
    train_clock = None  # (time, frames) when warm-up ended: the start of the timed part
    try:
        batches = iter(collector if collector.total_frames else ())  # 0 frames left: a finished run
        while True:
            if train_clock is None and frames >= warmup:
                timeit.erase()
                train_clock = (time.time(), frames)
            with timeit("collect"):
                data = next(batches, None)
            if data is None:  # the budget is collected
                break
            before, frames = frames, frames + data.numel()
            with timeit("replay_extend"):
                flat = data.reshape(-1)
                if nstep is None:
                    stored = flat.select(*TRANSITION_KEYS)
                else:  # per env stream (time last), across batches: a step waits for the n steps after it
                    # (flatten, not reshape(-1): TensorDict sizes an empty batch as 1 row)
                    stored = nstep.inv(data.select(*TRANSITION_KEYS)).flatten(0, -1)
                if absorbing is not None:
                    stored = absorbing.add_absorbing_transitions(stored)
                if stored.shape[0]:  # (the first batches of a run can all be waiting)
                    replay.extend(stored)
                    if recent is not replay:
                        recent.extend(stored)
            # Algorithm 1: every finished trajectory with r_e > C joins the teacher buffer.
            with timeit("teacher_extend"):
                if cfg.algo.adaptive:
                    teacher.extend(data)
            alpha_before = alpha_scheduler.alpha
            alpha = alpha_scheduler.step(frames=frames, num_promoted=teacher.writer.num_promoted)
            if alpha != alpha_before:
                metrics["alpha_switch_frame"] = frames
            done = flat["next", "done"].squeeze(-1)
            best_policy.observe(flat["next", "episode_return"][done].reshape(-1), before=before, frames=frames)
            if done.any():
                metrics["train/dense_return"] = flat["next", "episode_return"][done].mean()
                metrics["train/delayed_reward"] = flat["next", "reward"][done].mean()
                metrics["train/episode_length"] = flat["step_count"][done].float().mean() + 1
            if rnd is not None:
                metrics["train/intrinsic_reward"] = flat["next", "intrinsic_reward"].mean()

            # The authors' order at a shared frame: the TD3 block, then the D block. Neither the
            # buffers nor D change inside a block, so its batches are drawn (and rewarded by the
            # current D) in one call.
            num_updates = crossings(o.train_every_frames, warmup, before, frames) * o.updates_per_train
            if num_updates and o.actor_lr_decay is not None:  # a function of frames: a resume continues it
                metrics["sail/actor_lr"] = actor_lr(cfg, before)
                for group in optimizers["actor"].param_groups:
                    group["lr"] = metrics["sail/actor_lr"]
            if num_updates:
                with timeit("sample"), reduced_precision:  # the D reward too, with precision=bf16
                    block = sail_batches.sample(o.batch_size, teacher_fraction=alpha, num_batches=num_updates)
                metrics["sail/d_reward_mean" if uses_discriminator else "sail/env_reward_mean"] = block[
                    "next", "reward"
                ].mean()
                last = {}
                if drift is not None:
                    drift.start(block[0])
                for batch in block.unbind(0):
                    gradient_steps += 1
                    with timeit("update"):
                        last.update(
                            update(
                                batch,
                                update_actor=gradient_steps % o.policy_delay == 0
                                and gradient_steps >= o.actor_updates_after,
                            )
                        )
                metrics.update({f"sail/{key}": value for key, value in last.items()})
                if drift is not None:
                    metrics.update(drift.measure())
                if alpha < 1:  # the batch holds agent rows
                    metrics.update(actor_saturation(cfg, actor, batch))
            num_d_steps = crossings(d.every_frames, warmup, before, frames) * d.steps if uses_discriminator else 0
            if num_d_steps:
                with timeit("sample"):
                    d_block = d_batches.sample(2 * d.batch_size, teacher_fraction=0.5, num_batches=num_d_steps)
                with timeit("discriminator"):
                    metrics.update(
                        discriminator_block(
                            cfg, d_loss, optimizers["discriminator"], d_block, rnd_update if rnd is not None else None
                        )
                    )
            # NaN/inf stops the run here, at the logging cadence (and before any checkpoint), before
            # the weights reach the workers, an evaluation or a log.
            log_now = frames - last_log >= cfg.logger.log_every_frames or crossings(
                cfg.eval.every_frames, 0, before, frames
            )
            if log_now or crossings(cfg.checkpoint.every_frames, 0, before, frames):
                divergence(metrics, frame=frames, checkpoint=last_checkpoint(run_dir, run))
            # Worker processes or Ray actors act with a copy of the policy.
            collector.update_policy_weights_()

            with timeit("eval"):
                if crossings(cfg.eval.every_frames, 0, before, frames):
                    metrics["eval/return"] = record_evaluation(eval_env, actor, loss, cfg, run, frames, teacher_return)
                    if other_eval_env is not None:
                        metrics[f"eval/return_{other_actor}"] = evaluate_actor(
                            other_eval_env, actor, loss, other_actor, cfg.eval.episodes, cfg.env.max_episode_steps
                        )
                if crossings(cfg.eval.video_every_frames, 0, before, frames):
                    log_video(loggers, render_env, actor, cfg, run_dir, frames)
            with timeit("log"):
                fps = (frames - start_frames) / max(time.time() - start, 1e-9)
                metrics.update(
                    {
                        "teacher/threshold": teacher.writer.threshold,
                        "teacher/num_promoted": teacher.writer.num_promoted,
                        "teacher/num_trajectories": teacher.writer.num_trajectories,
                        "teacher/size": len(teacher),
                        "replay/size": len(replay),
                        "alpha": alpha,
                        "time/fps": fps,
                    }
                )
                if log_now:
                    log_metrics(loggers, {**metrics, **timeit.todict(prefix="time")}, frames)
                    metrics.pop("eval/return", None)
                    metrics.pop(f"eval/return_{other_actor}", None)
                    metrics.pop("alpha_switch_frame", None)
                    last_log = frames
                pbar.update(data.numel())
                pbar.set_postfix(
                    ret=f"{float(metrics.get('train/dense_return', float('nan'))):.0f}",
                    eval=f"{run['evals'][-1][1]:.0f}" if run["evals"] else "-",
                    C=f"{teacher.writer.threshold:.0f}",
                    alpha=f"{alpha:.2f}",
                    fps=f"{fps:.0f}",
                )
            with timeit("checkpoint"):
                if crossings(cfg.checkpoint.every_frames, 0, before, frames):
                    save(frames, gradient_steps)
    finally:  # also on a DivergenceError: worker processes and Ray actors end with the run
        collector.shutdown()
        pbar.close()
    end = time.time()
    save(frames, gradient_steps)

    evals = [value for _, value in run["evals"]]
    # the best policy's deterministic episodes, on the stream examples/evaluate.py uses by default
    best = best_policy.record()
    if best["frames"] is not None and cfg.eval.best_policy.episodes:
        with best_policy.params(cfg.eval.actor).to_module(actor, preserve_module_state=False):
            best["eval_return"] = evaluate(
                make_env(cfg, cfg.seed + 20_000), actor, cfg.eval.best_policy.episodes, cfg.env.max_episode_steps
            )
        best.update(actor=str(cfg.eval.actor), episodes=cfg.eval.best_policy.episodes, seed=cfg.seed + 20_000)
    write_run_summary(
        run_dir,
        cfg,
        teacher_return=teacher_return,
        alpha_switch_frame=alpha_scheduler.switched_at_frame,
        teacher_source=teacher_source,
        frames=frames,
        gradient_steps=gradient_steps,
        final_eval_return=evals[-1] if evals else None,
        best_eval_return=max(evals) if evals else None,
        passed_teacher_at_frame=run["passed_teacher_at"],
        fall_share=fall_share(run["evals"], teacher_return),
        best_policy=best,
        evaluated_actor=str(cfg.eval.actor),
        resumes=run["resumes"],
        starts=run["starts"],
        wall_seconds=run["wall_seconds"],
        num_promoted=teacher.writer.num_promoted,
        teacher_threshold=teacher.writer.threshold,
        frames_per_second=(frames - start_frames) / max(end - start, 1e-9),
        **train_timing(train_clock, end=end, frames=frames),
    )


if __name__ == "__main__":
    main()
