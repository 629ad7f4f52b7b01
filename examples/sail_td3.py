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
The loop's steps, and each method's variations of them, are the objects of ``loop.py``.
Each run writes to its folder (``hydra.run.dir``): the resolved config, TorchRL logger
outputs (``logs/``), ``learning_curve.png``, ``summary.json``, ``best_policy.pt``,
``best_evaluated_policy.pt`` and ``checkpoint/`` (``resume=true`` continues from it).
"""

from __future__ import annotations

from mujoco_gl import check_mujoco_gl

check_mujoco_gl()  # before TorchRL imports MuJoCo, which loads the MUJOCO_GL backend on import

import hydra
import tqdm
from config_schema import register_config_schema
from loop import (
    RandomEpisodesUntil,
    TeacherUpdate,
    finished_episodes,
    make_eval_envs,
    make_evaluations,
    make_learning_blocks,
    make_prioritized_update,
    make_recent,
    make_td3_batches,
    make_td3_block,
    make_transition_store,
)
from run_utils import (
    EXAMPLES_DIR,
    BestEvaluatedPolicy,
    BestPolicy,
    RunCheckpoint,
    RunClock,
    actor_weights,
    crossings,
    evaluate_kept_policy,
    log_metrics,
    make_actor_average,
    make_loggers,
    make_run,
    start_run,
    write_run_summary,
)
from torchrl import timeit
from torchrl.checkpoint import Checkpoint, GlobalRNGState
from utils import (
    FilledRows,
    make_absorbing,
    make_agent,
    make_collector,
    make_discriminator,
    make_env,
    make_eval_env,
    make_losses,
    make_optimizers,
    make_replay,
    make_reward,
    make_rnd,
    make_teacher,
    make_update,
)

from torchrl_sail import DivergenceCheck, MixedReplayBuffer
from torchrl_sail.harness import BEST_EVALUATED_POLICY, BEST_POLICY, start_or_resume

register_config_schema()  # the typed schema conf/config.yaml extends: Hydra checks every value against it

# state a checkpoint of an earlier version lacks, kept from the resume on
STARTS_EMPTY_ON_RESUME = ("best_evaluated_policy",)


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
def main(cfg):  # noqa: F821
    run_dir, resuming = start_run(cfg, "sail_td3.py")  # algo=gail, pofd: gail.py; algo=bc: bc.py
    if resuming is None:
        return

    # --- env, teacher, buffers (everything is validated before training starts)
    env, eval_envs = make_env(cfg, cfg.seed), make_eval_envs(cfg, make_eval_env)
    rnd, rnd_loss = make_rnd(cfg, env)  # SAIL-RND's curiosity bonus (None for the other methods)
    # DAC's demonstrations store their absorbing transitions with the zero action
    teacher, teacher_return, teacher_source = make_teacher(cfg, env, make_absorbing(cfg))
    replay = make_replay(cfg.env.replay_size, cfg.device)
    recent = make_recent(cfg, replay)  # what D learns the agent's side from
    store = make_transition_store(cfg, replay, recent, env.action_spec)

    # --- networks, losses, optimizers
    actor, critic, exploration_policy = make_agent(cfg, env)
    discriminator = make_discriminator(cfg, env)
    loss, target_updater, alpha_scheduler, d_loss = make_losses(cfg, actor, critic, discriminator, env.action_spec)
    optimizers = make_optimizers(cfg, loss, discriminator, rnd)
    # eval.average_frames: an average of the actor's weights over that many frames, to evaluate and ship
    average = make_actor_average(cfg, loss)
    actors = actor_weights(loss, average)  # online, TD3's target and the average, by eval.actor's names
    # the authors' best policy: the actors at the best mean of the last training returns
    best_policy = BestPolicy(actors, every_frames=cfg.eval.best_policy.every_frames, window=cfg.eval.best_policy.window)
    # and the actors at the best periodic evaluation (Stable-Baselines3's EvalCallback rule)
    best_evaluated = BestEvaluatedPolicy(actors)

    # --- Algorithm 1's TD3 batches get the reward of the *current* D (and RND predictor) at sample
    # time (reward.source=env: the env's alone), D once per distinct stored row of a block; DDPGfD's
    # (algo.per) are drawn by prioritized replay over the demonstrations and the replay together.
    reward = make_reward(cfg, discriminator, rnd, row_id_key="row_id")
    sail_batches = make_td3_batches(cfg, teacher, replay, reward)

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
        "best_evaluated_policy": best_evaluated,
        **{f"optim_{name}": optimizer for name, optimizer in optimizers.items()},
        **({"recent": FilledRows(recent)} if recent is not replay else {}),
        **({"rnd": rnd} if rnd is not None else {}),
        **({"actor_average": average} if average is not None else {}),
        # components load in name order: the priorities after the replay's rows they are for
        **({"replay_priorities": sail_batches} if cfg.algo.per is not None else {}),
    }
    checkpoint = Checkpoint(**stateful)
    start_or_resume(
        checkpoint,
        run_dir,
        run,
        resuming,
        optimizers=optimizers.values(),
        config=cfg,
        code_dir=EXAMPLES_DIR,
        may_start_empty=STARTS_EMPTY_ON_RESUME,
    )
    if resuming:
        # The env restarts on a fresh episode: a trajectory cut by the stop is not offered.
        teacher.writer.clear_unfinished()
        env.set_seed(cfg.seed + run["frames"])  # a different episode stream than the one before the stop
    loggers = make_loggers(cfg, run_dir, run["loggers"])

    # --- Algorithm 1's steps
    update_teacher = TeacherUpdate(
        teacher, alpha_scheduler, adaptive=cfg.algo.adaptive, max_promoted=cfg.algo.max_promoted
    )
    evaluations = make_evaluations(
        cfg, eval_envs, actor, actors, run, teacher_return, loggers, run_dir, best_evaluated=best_evaluated
    )
    update = make_prioritized_update(cfg, make_update(cfg, loss, optimizers, target_updater), sail_batches, loss)
    td3_block = make_td3_block(
        cfg,
        sail_batches,
        update,
        actor,
        loss,
        alpha_scheduler,
        optimizers,
        gradient_steps=run["gradient_steps"],
        target_updater=target_updater,
    )
    d_batches = MixedReplayBuffer(teacher, recent)
    learning_blocks = make_learning_blocks(cfg, td3_block, d_batches, d_loss, optimizers, rnd, rnd_loss)

    frames = run["frames"]
    if cfg.collector.random_until_actor:
        exploration_policy = RandomEpisodesUntil(exploration_policy, env.action_spec, lambda: td3_block.actor_started)
    collector = make_collector(cfg, env, exploration_policy, frames=frames)
    pbar = tqdm.tqdm(total=cfg.collector.total_frames, initial=frames, unit="frames")
    clock = RunClock(run, frames, warmup=cfg.collector.init_random_frames)
    # NaN/inf in a logged loss or a parameter stops the run before it is logged or saved
    divergence = DivergenceCheck({"loss": loss, "discriminator": discriminator, **({"rnd": rnd} if rnd else {})})
    save = RunCheckpoint(
        checkpoint,
        run_dir,
        run,
        loggers=loggers,
        divergence=divergence,
        clock=clock,
        # after the checkpoint they match
        after_save=[
            lambda: best_policy.write(run_dir / BEST_POLICY),
            lambda: best_evaluated.write(run_dir / BEST_EVALUATED_POLICY),
        ],
    )
    metrics, once, last_log = {}, {}, frames  # once: logged at the next log only
    try:
        for data in clock.batches(collector, frames):
            before, frames = frames, frames + data.numel()
            with timeit("replay_extend"):
                store(data)
            with timeit("teacher_extend"):  # every finished trajectory with r_e > C joins the teacher buffer
                alpha, switched = update_teacher(data, frames)
            once.update(switched)
            metrics.update(finished_episodes(data, best_policy, before=before, frames=frames))
            for block in learning_blocks:  # optim.block_order: the SAIL authors' TD3 block, then D block
                metrics.update(block(before, frames, data))
            if average is not None:  # follows the weights the blocks left
                average.update(before=before, frames=frames)
            # NaN/inf stops the run here, at the logging cadence (and before any checkpoint), before
            # the weights reach the workers, an evaluation or a log.
            log_now = frames - last_log >= cfg.logger.log_every_frames or crossings(
                cfg.eval.every_frames, 0, before, frames
            )
            checkpoint_now = crossings(cfg.checkpoint.every_frames, 0, before, frames)
            if log_now or checkpoint_now:
                save.check(metrics, frames)
            collector.update_policy_weights_()  # worker processes or Ray actors act with a copy of the policy
            with timeit("eval"):
                once.update(evaluations(before, frames))
            with timeit("log"):
                metrics.update(
                    {
                        "teacher/threshold": teacher.writer.threshold,
                        "teacher/num_promoted": teacher.writer.num_promoted,
                        "teacher/num_trajectories": teacher.writer.num_trajectories,
                        "teacher/size": len(teacher),
                        "replay/size": len(replay),
                        "alpha": alpha,
                        "time/fps": clock.fps(frames),
                    }
                )
                if log_now:
                    log_metrics(loggers, {**metrics, **once, **timeit.todict(prefix="time")}, frames)
                    once, last_log = {}, frames
                pbar.update(data.numel())
                pbar.set_postfix(
                    ret=f"{float(metrics.get('train/dense_return', float('nan'))):.0f}",
                    eval=f"{run['evals'][-1][1]:.0f}" if run["evals"] else "-",
                    C=f"{teacher.writer.threshold:.0f}",
                    alpha=f"{alpha:.2f}",
                    fps=f"{metrics['time/fps']:.0f}",
                )
            with timeit("checkpoint"):
                if checkpoint_now:
                    save(metrics, frames=frames, gradient_steps=td3_block.gradient_steps)
    finally:  # also on a DivergenceError: worker processes and Ray actors end with the run
        collector.shutdown()
        pbar.close()
    clock.stop()
    save(metrics, frames=frames, gradient_steps=td3_block.gradient_steps)

    write_run_summary(
        run_dir,
        cfg,
        run,
        teacher_return=teacher_return,
        teacher_source=teacher_source,
        clock=clock,
        alpha_switch_frame=alpha_scheduler.switched_at_frame,
        best_policy=evaluate_kept_policy(cfg, best_policy, actor, make_eval_env),
        best_evaluated_policy=evaluate_kept_policy(cfg, best_evaluated, actor, make_eval_env),
        evaluated_actor=str(cfg.eval.actor),
        num_promoted=teacher.writer.num_promoted,
        teacher_threshold=teacher.writer.threshold,
    )


if __name__ == "__main__":
    main()
