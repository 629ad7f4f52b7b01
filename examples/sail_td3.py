"""SAIL (Self-Adaptive Imitation Learning) on MuJoCo with TorchRL: TD3 + discriminator
reward + an adaptive top-K teacher buffer, learning from one delayed reward per episode.

    python examples/sail_td3.py env=Walker2d-v4
    python examples/sail_td3.py env=Hopper-v4 teacher.path=../shared/data/teachers/expert_data_no_img_Hopper_scores_1500_episodes_1.npz
    python examples/sail_td3.py -m seed=0,1,2            # Hydra multirun

The default cadence is the authors' code: 10k random warm-up frames, then every 1000
frames 1000 TD3 steps on batches of 128 teacher + 128 agent rows (alpha = 0.5, dropped
to 0 at the first promoted trajectory) and every 500 frames 10 discriminator steps of
256 + 256 rows. Each run writes to its folder (``hydra.run.dir``): the resolved config,
TorchRL logger outputs (``logs/``), ``learning_curve.png``, ``summary.json`` and
``checkpoint.pt`` (``resume=true`` continues from it).
"""
from __future__ import annotations

import time
from pathlib import Path

import hydra
import torch
import tqdm
from hydra.core.hydra_config import HydraConfig
from omegaconf import OmegaConf

from torchrl_sail import DiscriminatorReward, MixedReplayBuffer
from torchrl_sail.data._keys import TRANSITION_KEYS
from utils import (
    CHECKPOINT,
    check_config,
    evaluate,
    load_checkpoint,
    load_replay_state,
    load_rng_state,
    load_teacher,
    log_metrics,
    logger_states,
    make_agent,
    make_collector,
    make_discriminator,
    make_env,
    make_losses,
    make_loggers,
    make_optimizers,
    make_replay,
    make_teacher_buffer,
    peak_memory_mb,
    plot_learning_curve,
    replay_state,
    rng_state,
    save_checkpoint,
    seed_everything,
    truncate_scalars,
    write_json,
)


def first_multiple_at_or_after(every: int, frame: int) -> int:
    return -(-max(frame, every) // every) * every


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
def main(cfg):  # noqa: F821
    check_config(cfg)
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    run_dir = Path(HydraConfig.get().runtime.output_dir)
    ckpt_path = run_dir / CHECKPOINT
    if ckpt_path.exists() and not cfg.resume:
        raise FileExistsError(
            f"{run_dir} already holds a run (checkpoint.pt). Continue it with resume=true, "
            f"or choose another folder with hydra.run.dir=..."
        )
    seed_everything(cfg.seed)

    # --- env, teacher, buffers (everything is validated before training starts)
    env = make_env(cfg, cfg.seed)
    eval_env = make_env(cfg, cfg.seed + 10_000)
    demos, teacher_meta = load_teacher(cfg, env)
    teacher_return = float(max(teacher_meta["episode_returns"]))
    teacher = make_teacher_buffer(cfg, demos)
    replay = make_replay(cfg.env.replay_size)
    # SAIL-OnPolicy trains D against the most recent transitions only.
    recent = make_replay(cfg.algo.recent_window) if cfg.algo.discriminator_agent_data == "recent" else replay

    # --- networks, losses, optimizers
    actor, critic, exploration_policy = make_agent(cfg, env)
    discriminator = make_discriminator(cfg, env)
    loss, target_updater, alpha_scheduler, d_loss = make_losses(
        cfg, actor, critic, discriminator, env.action_spec
    )
    optimizers = make_optimizers(cfg, loss, discriminator)
    # SAIL batches get the imitation reward of the *current* D at sample time.
    sail_batches = MixedReplayBuffer(teacher, replay, keys=list(TRANSITION_KEYS),
                                     transform=DiscriminatorReward(discriminator))
    d_batches = MixedReplayBuffer(teacher, recent, keys=list(TRANSITION_KEYS))

    # --- counters (all in env frames), possibly restored
    warmup = cfg.collector.init_random_frames
    frames = 0
    next_train = first_multiple_at_or_after(cfg.optim.train_every_frames, warmup)
    next_d = first_multiple_at_or_after(cfg.optim.discriminator.every_frames, warmup)
    next_eval = cfg.eval.every_frames or float("inf")
    next_ckpt = cfg.checkpoint.every_frames or float("inf")
    gradient_steps = 0
    history = {"eval": [], "passed_teacher_at": None}
    if cfg.resume:
        state = load_checkpoint(ckpt_path)
        for key in ("env.name", "algo.name", "seed"):
            saved = OmegaConf.select(OmegaConf.create(state["config"]), key)
            if saved != OmegaConf.select(cfg, key):
                raise ValueError(f"resume=true: {ckpt_path} was written with {key}={saved!r}, "
                                 f"this run has {key}={OmegaConf.select(cfg, key)!r}; use the same value.")
        loss.load_state_dict(state["loss"])
        discriminator.load_state_dict(state["discriminator"])
        for name, opt in optimizers.items():
            opt.load_state_dict(state["optimizers"][name])
        load_replay_state(replay, state["replay"])
        if recent is not replay:
            load_replay_state(recent, state["recent"])
        teacher.load_state_dict(state["teacher"])
        # The env restarts on a fresh episode: a trajectory cut by the stop is not offered.
        teacher.clear_unfinished()
        alpha_scheduler.load_state_dict(state["alpha_scheduler"])
        frames, next_train, next_d, next_eval, next_ckpt, gradient_steps = (
            state["counters"][k] for k in ("frames", "next_train", "next_d", "next_eval", "next_ckpt", "gradient_steps")
        )
        history = state["history"]
        load_rng_state(state["rng"])
        env.set_seed(cfg.seed + frames)  # a different episode stream than the one before the stop
        # Rows logged after the checkpoint are logged again by this run: drop them.
        truncate_scalars(run_dir, frames)
    else:
        OmegaConf.save(cfg, run_dir / "config.yaml", resolve=True)
    loggers = make_loggers(cfg, run_dir, state.get("loggers") if cfg.resume else None)

    def checkpoint():
        save_checkpoint(ckpt_path, {
            "loss": loss.state_dict(),
            "discriminator": discriminator.state_dict(),
            "optimizers": {name: opt.state_dict() for name, opt in optimizers.items()},
            "replay": replay_state(replay),
            "recent": replay_state(recent) if recent is not replay else None,
            "teacher": teacher.state_dict(),
            "alpha_scheduler": alpha_scheduler.state_dict(),
            "counters": {"frames": frames, "next_train": next_train, "next_d": next_d,
                         "next_eval": next_eval, "next_ckpt": next_ckpt, "gradient_steps": gradient_steps},
            "history": history,
            "rng": rng_state(),
            "loggers": logger_states(loggers),
            "config": OmegaConf.to_container(cfg, resolve=True),
        })

    # A resumed run collects only what is left of the budget (possibly nothing).
    collector = make_collector(cfg, env, exploration_policy, frames=frames) if frames < cfg.collector.total_frames else []

    def sail_update() -> dict:
        nonlocal gradient_steps
        n_teacher, n_agent = MixedReplayBuffer.split(cfg.optim.batch_size, float(loss.alpha))
        batch = sail_batches.sample(n_teacher, n_agent)
        loss_q, info = loss.value_loss(batch)
        optimizers["critic"].zero_grad()
        loss_q.backward()
        optimizers["critic"].step()
        out = {"sail/loss_qvalue": loss_q.detach(), "sail/q_mean": info["pred_value"].mean(),
               "sail/d_reward_mean": batch["next", "reward"].mean()}
        gradient_steps += 1
        if gradient_steps % cfg.optim.policy_delay == 0:
            loss_a, _ = loss.actor_loss(batch)
            optimizers["actor"].zero_grad()
            loss_a.backward()
            optimizers["actor"].step()
            target_updater.step()
            out["sail/loss_actor"] = loss_a.detach()
        return out

    def discriminator_update() -> dict:
        n = cfg.optim.discriminator.batch_size
        out = d_loss(d_batches.sample(n, n))
        total = sum(v for k, v in out.items() if k.startswith("loss_"))
        optimizers["discriminator"].zero_grad()
        total.backward()
        optimizers["discriminator"].step()
        return {f"d/{k}": v for k, v in out.items()}

    pbar = tqdm.tqdm(total=cfg.collector.total_frames, initial=frames, unit="frames")
    start, start_frames = time.time(), frames
    metrics, last_log = {}, frames
    recent_returns = []
    for data in collector:
        frames += data.numel()
        flat = data.reshape(-1)
        replay.extend(flat.select(*TRANSITION_KEYS))
        if recent is not replay:
            recent.extend(flat.select(*TRANSITION_KEYS))
        # Algorithm 1: every finished trajectory with r_e > C joins the teacher buffer.
        if cfg.algo.adaptive:
            teacher.extend(data)
        alpha_before = float(loss.alpha)
        alpha_scheduler.step(frames=frames, num_promoted=teacher.num_promoted)
        done = flat["next", "done"].squeeze(-1)
        if done.any():
            recent_returns = flat["next", "episode_return"][done].squeeze(-1).tolist()
            metrics["train/dense_return"] = sum(recent_returns) / len(recent_returns)
            metrics["train/delayed_reward"] = flat["next", "reward"][done].mean()
            metrics["train/episode_length"] = flat["step_count"][done].float().mean() + 1

        # The authors' order at a shared frame: the TD3 block, then the D block.
        while frames >= next_train:
            for _ in range(cfg.optim.updates_per_train):
                metrics.update(sail_update())
            next_train += cfg.optim.train_every_frames
        while frames >= next_d:
            for _ in range(cfg.optim.discriminator.steps):
                metrics.update(discriminator_update())
            next_d += cfg.optim.discriminator.every_frames
        # Worker processes or Ray actors act with a copy of the policy.
        collector.update_policy_weights_()

        if frames >= next_eval:
            returns = evaluate(eval_env, actor, cfg.eval.episodes, cfg.env.max_episode_steps)
            eval_return = sum(returns) / len(returns)
            history["eval"].append((frames, eval_return))
            if history["passed_teacher_at"] is None and eval_return > teacher_return:
                history["passed_teacher_at"] = frames
            metrics["eval/return"] = eval_return
            next_eval += cfg.eval.every_frames

        fps = (frames - start_frames) / max(time.time() - start, 1e-9)
        metrics.update({
            "teacher/threshold": teacher.threshold, "teacher/num_promoted": teacher.num_promoted,
            "teacher/num_trajectories": teacher.num_trajectories, "teacher/size": len(teacher),
            "replay/size": len(replay), "alpha": float(loss.alpha), "time/fps": fps,
        })
        if float(loss.alpha) != alpha_before:
            metrics["alpha_switch_frame"] = frames
        if frames - last_log >= cfg.logger.log_every_frames or "eval/return" in metrics:
            log_metrics(loggers, metrics, frames)
            metrics.pop("eval/return", None)
            last_log = frames
        pbar.update(data.numel())
        pbar.set_postfix(
            ret=f"{metrics.get('train/dense_return', float('nan')):.0f}",
            eval=f"{history['eval'][-1][1]:.0f}" if history["eval"] else "-",
            C=f"{teacher.threshold:.0f}", alpha=f"{float(loss.alpha):.2f}", fps=f"{fps:.0f}",
        )
        if frames >= next_ckpt:
            checkpoint()
            next_ckpt += cfg.checkpoint.every_frames
    if collector:
        collector.shutdown()
    pbar.close()
    checkpoint()

    curve = plot_learning_curve(
        run_dir, teacher_return=teacher_return,
        alpha_switch_frame=alpha_scheduler.switched_at_frame,
        title=f"SAIL ({cfg.algo.name}) on {cfg.env.name}, seed {cfg.seed}",
    )
    evals = history["eval"]
    write_json(run_dir / "summary.json", {
        "env": cfg.env.name, "algo": cfg.algo.name, "seed": cfg.seed, "frames": frames,
        "teacher_return": teacher_return, "teacher_source": teacher_meta.get("source"),
        "final_eval_return": evals[-1][1] if evals else None,
        "best_eval_return": max(r for _, r in evals) if evals else None,
        "passed_teacher_at_frame": history["passed_teacher_at"],
        "alpha_switched_at_frame": alpha_scheduler.switched_at_frame,
        "num_promoted": teacher.num_promoted, "teacher_threshold": teacher.threshold,
        "gradient_steps": gradient_steps, "frames_per_second": (frames - start_frames) / max(time.time() - start, 1e-9),
        "peak_memory_mb": peak_memory_mb(), "learning_curve": curve.name,
    })


if __name__ == "__main__":
    main()
