"""Makes a deliberately sub-optimal SAIL teacher: TD3 on the dense reward for a short budget,
then one deterministic trajectory saved with its metadata (env, return, length, how it was made).

    python examples/make_teacher.py env=Hopper-v4 frames=60000 stop_at_return=1000

The demonstration is recorded with the same observation layout SAIL uses (time feature on)
and stored in the project's format (``save_demonstrations``), dense rewards included: SAIL
turns them into the delayed reward when it loads the file.
"""

from __future__ import annotations

import time

import hydra
import torch
import tqdm
from config_schema import register_config_schema
from run_utils import seed_everything, set_cpu_math
from torchrl.collectors import Collector
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.objectives import SoftUpdate, TD3Loss
from utils import env_device, env_kwargs, make_agent, make_replay

from torchrl_sail import TRANSITION_KEYS, make_sail_env, save_demonstrations

register_config_schema()  # the typed schema conf/make_teacher.yaml extends (MakeTeacherConfig)


def make_env(cfg, seed):
    env = make_sail_env(
        cfg.env.name,
        max_episode_steps=cfg.env.max_episode_steps,
        delayed_reward=False,
        device=env_device(cfg),
        env_kwargs=env_kwargs(cfg),
    )
    env.set_seed(seed)
    return env


@torch.no_grad()
def record(env, actor, max_steps):
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        rollout = env.rollout(max_steps, actor, break_when_any_done=True)
    return rollout, float(rollout["next", "reward"].sum())


@hydra.main(version_base="1.3", config_path="../conf", config_name="make_teacher")
def main(cfg):  # noqa: F821
    set_cpu_math(cfg.threads, cfg.flush_denormal)
    seed_everything(cfg.seed)
    env, eval_env = make_env(cfg, cfg.seed), make_env(cfg, cfg.seed + 10_000)
    actor, critic, exploration_policy = make_agent(cfg, env)
    loss = TD3Loss(actor, critic, action_spec=env.action_spec, loss_function="l2")
    loss.make_value_estimator(gamma=cfg.gamma)
    loss.set_keys(terminated="done")  # same convention as SAIL's default
    updater = SoftUpdate(loss, tau=cfg.tau)
    critic_optim = torch.optim.Adam(loss.qvalue_network_params.flatten_keys().values(), lr=cfg.lr)
    actor_optim = torch.optim.Adam(loss.actor_network_params.flatten_keys().values(), lr=cfg.lr)
    replay = make_replay(cfg.frames, cfg.device)
    collector = Collector(
        env,
        exploration_policy,
        frames_per_batch=cfg.frames_per_batch,
        total_frames=cfg.frames,
        init_random_frames=cfg.init_random_frames,
    )

    best = None  # (return, rollout, frames) of the best recordable deterministic episode
    frames, updates, start = 0, 0, time.time()
    pbar = tqdm.tqdm(total=cfg.frames, unit="frames")
    for data in collector:
        frames += data.numel()
        replay.extend(data.reshape(-1).select(*TRANSITION_KEYS))
        if frames >= cfg.init_random_frames:
            for _ in range(cfg.updates_per_batch):
                batch = replay.sample(cfg.batch_size)
                loss_q, _ = loss.value_loss(batch)
                critic_optim.zero_grad()
                loss_q.backward()
                critic_optim.step()
                updates += 1
                if updates % cfg.policy_delay == 0:
                    loss_a, _ = loss.actor_loss(batch)
                    actor_optim.zero_grad()
                    loss_a.backward()
                    actor_optim.step()
                    updater.step()
        if frames % cfg.eval_every_frames < data.numel():
            rollout, ret = record(eval_env, actor, cfg.env.max_episode_steps)
            if (cfg.max_return is None or ret <= cfg.max_return) and (best is None or ret > best[0]):
                best = (ret, rollout, frames)
            pbar.set_postfix(eval=f"{ret:.0f}", best=f"{best[0]:.0f}" if best else "-")
            if cfg.stop_at_return is not None and ret >= cfg.stop_at_return:
                break
        pbar.update(data.numel())
    collector.shutdown()
    if best is None:
        raise RuntimeError(f"no deterministic episode with return <= max_return={cfg.max_return} was recorded")

    ret, rollout, at_frames = best
    rollout = rollout.select(*TRANSITION_KEYS, "step_count")
    metadata = {
        "env_id": cfg.env.name,
        "episode_returns": [ret],
        "episode_lengths": [rollout.numel()],
        "made_by": "examples/make_teacher.py: TD3 on the dense reward, one deterministic episode",
        "td3_frames": at_frames,
        "seed": cfg.seed,
        "time_feature": True,
        "max_episode_steps": cfg.env.max_episode_steps,
        "wall_time_s": round(time.time() - start, 1),
    }
    path = save_demonstrations(cfg.out, rollout, metadata)
    print(f"teacher for {cfg.env.name}: return {ret:.1f}, {rollout.numel()} steps -> {path}")


if __name__ == "__main__":
    main()
