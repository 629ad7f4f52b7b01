"""Behaviour cloning on the teacher demonstrations (``algo=bc``), the offline baseline.

    python examples/bc.py algo=bc env=Hopper-v4 teacher.path=<teacher.npz|dataset folder>

The actor (the same network as TD3's in ``sail_td3.py``) regresses the teacher's actions with
TorchRL's ``BCLoss`` (MSE), offline: no env frames are collected. It trains ``algo.bc.epochs``
epochs of ``max(1, teacher transitions // algo.bc.batch_size)`` steps each (the SAIL authors'
``pretrain_with_buffer``), then is evaluated like
every other method, and the run folder holds the same files (``summary.json`` with
``"offline": true`` and ``frames: 0``, ``eval/return`` logged at frame 0, a checkpoint). The
same config (``conf/config.yaml``) and overrides as ``sail_td3.py``; ``algo=`` must name a
behaviour-cloning method (``algo.learner=bc``).
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
    actor_returns,
    evaluation_metrics,
    log_metrics,
    logger_states,
    make_loggers,
    make_run,
    start_run,
    write_run_summary,
)
from torchrl.checkpoint import Checkpoint, GlobalRNGState
from torchrl.objectives import BCLoss
from utils import make_agent, make_env, make_eval_env, make_teacher
from video import log_video, make_render_env

from torchrl_sail import DivergenceCheck
from torchrl_sail.harness import add_evaluation, checkpoint_dir, start_or_resume

register_config_schema()  # the typed schema conf/config.yaml extends: Hydra checks every value against it


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
def main(cfg):  # noqa: F821
    run_dir, resuming = start_run(cfg, "bc.py")  # the off-policy methods: sail_td3.py; algo=gail, pofd: gail.py
    if resuming is None:
        return

    env = make_env(cfg, cfg.seed)  # its specs: BC trains offline
    teacher, teacher_return, teacher_source = make_teacher(cfg, env)
    actor, _, _ = make_agent(cfg, env)
    loss = BCLoss(actor, loss_function="l2")
    optimizer = torch.optim.Adam(loss.actor_network_params.flatten_keys().values(), lr=cfg.algo.bc.lr)
    # the authors' epochs: whole batches of the teacher buffer, at least one
    steps = cfg.algo.bc.epochs * max(1, len(teacher) // cfg.algo.bc.batch_size)

    run = make_run(cfg)
    checkpoint = Checkpoint(actor=actor, optim_actor=optimizer, rng=GlobalRNGState(), run=run)
    # The checkpoint is written once training is done: a resumed BC run has nothing left to train,
    # and its logs (indexed by BC steps, not frames) stay as they are.
    start_or_resume(
        checkpoint,
        run_dir,
        run,
        resuming,
        optimizers=[optimizer],
        truncate_logs=False,
        config=cfg,
        code_dir=EXAMPLES_DIR,
    )
    loggers = make_loggers(cfg, run_dir, run["loggers"])

    divergence = DivergenceCheck({"loss": loss}, unit="BC step")  # BC's checkpoint is written once, after training
    start = time.time()
    for step in tqdm.trange(run["gradient_steps"], steps, unit="steps", desc="BC"):
        out = loss(teacher.sample(cfg.algo.bc.batch_size))
        out["loss_bc"].backward()
        optimizer.step()
        optimizer.zero_grad(set_to_none=True)
        if (step + 1) % 10 == 0 or step + 1 == steps:
            divergence({"bc/loss": out["loss_bc"]}, frame=step + 1)
            log_metrics(loggers, {"bc/loss": out["loss_bc"]}, step + 1)  # x axis: BC steps
    if run["gradient_steps"] < steps:
        run["gradient_steps"], run["train_seconds"] = steps, time.time() - start
        eval_env = make_eval_env(cfg, cfg.seed + 10_000, cfg.eval.episodes)
        returns = actor_returns(eval_env, actor, None, cfg.eval.episodes, cfg.env.max_episode_steps)
        metrics = evaluation_metrics(returns, teacher_return)
        add_evaluation(run, 0, metrics["eval/return"], teacher_return)
        log_metrics(loggers, metrics, 0)
        if cfg.eval.video_every_frames:  # offline: the one evaluation (frame 0) gets the one video
            log_video(loggers, make_render_env(cfg, cfg.seed + 30_000, cfg.eval.video_size), actor, cfg, run_dir, 0)
        run["loggers"] = logger_states(loggers)
        checkpoint.save(checkpoint_dir(run_dir))

    write_run_summary(
        run_dir,
        cfg,
        run,
        teacher_return=teacher_return,
        teacher_source=teacher_source,
        offline=True,
        train_seconds=run["train_seconds"],
    )


if __name__ == "__main__":
    main()
