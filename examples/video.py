"""Videos of a policy: one deterministic episode rendered offscreen by MuJoCo, written to MP4 or GIF.

Used by ``evaluate.py video=true`` and by training (``eval.video_every_frames``). Frames come
from TorchRL's ``PixelRenderTransform`` (``make_sail_env(render_size=...)``); files are written
with imageio (MP4 through the ffmpeg binary of ``imageio-ffmpeg``: ``pip install -e '.[video]'``):
TorchRL's own MP4 writer (``CSVLogger(video_format="mp4")``) needs torchcodec and the system's
FFmpeg libraries, which a pip install does not bring.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np
import torch
from mujoco_gl import GL_HELP
from torchrl.envs import ExplorationType, set_exploration_type
from utils import make_env

from torchrl_sail.harness import render_fps


def make_render_env(cfg, seed: int, size):
    """The run's env (same observation layout as training) that also renders ``"pixels"``.

    A PPO run's env normalises observations: give it the training statistics, frozen, before
    recording (``utils.copy_observation_norm``).

    Raises:
        RuntimeError: when MuJoCo cannot render here, naming ``MUJOCO_GL`` and the packages to install.
    """
    env = make_env(cfg, seed, render_size=size)
    try:
        env.reset()  # renders the first frame: fails here without a usable GL backend
    except Exception as err:  # EGL/OSMesa/GLFW failures surface as many exception types
        env.close()
        raise RuntimeError(
            f"Cannot render {cfg.env.name} with MUJOCO_GL={os.environ.get('MUJOCO_GL')!r} "
            f"({type(err).__name__}: {err}). {GL_HELP}"
        ) from err
    env.set_seed(seed)  # after the probe: the first recorded episode is the seed's first
    return env


@torch.no_grad()
def record_episode(env, actor, max_steps: int):
    """One deterministic episode of ``actor`` on a render env: ``(frames [T + 1, H, W, 3] uint8, rollout)``."""
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        rollout = env.rollout(max_steps, actor, break_when_any_done=True)
    frames = torch.cat([rollout["pixels"][:1], rollout["next", "pixels"]])  # the reset frame, then every step
    return frames.cpu().numpy(), rollout


def video_fps(env) -> int:
    """Real time: the env's own rendering rate (MuJoCo tasks: 1 / dt, e.g. 125 for Hopper)."""
    return render_fps(env, default=30)


def write_video(frames: np.ndarray, path: Path, fps: int) -> Path:
    """Writes ``frames`` (uint8 ``[T, H, W, 3]``) to ``path``: ``.mp4`` (H.264) or ``.gif``, atomically."""
    import imageio.v3 as iio

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    if path.suffix == ".mp4":
        if importlib.util.find_spec("imageio_ffmpeg") is None:
            raise ImportError("MP4 videos need imageio-ffmpeg: pip install -e '.[video]' (or write a .gif)")
        iio.imwrite(tmp, frames, fps=fps, codec="libx264", plugin="FFMPEG", macro_block_size=8)
    elif path.suffix == ".gif":
        # GIF frame delays are multiples of 10 ms: at most 100 frames/s
        iio.imwrite(tmp, frames, duration=max(10, round(1000 / fps, -1)), loop=0)
    else:
        raise ValueError(f"video file {path}: use a .mp4 or .gif suffix")
    os.replace(tmp, path)
    return path


def log_video(loggers: dict, env, actor, cfg, run_dir: Path, frames: int) -> Path:
    """Training's video: one deterministic episode to ``videos/eval_<frames>.<format>``, and to wandb if it logs."""
    pixels, _ = record_episode(env, actor, cfg.env.max_episode_steps)
    fps = video_fps(env)
    path = write_video(pixels, run_dir / "videos" / f"eval_{frames}.{cfg.eval.video_format}", fps)
    if "wandb" in loggers:  # TorchRL's WandbLogger takes [B, T, C, H, W] and encodes it (moviepy) into the run
        video = torch.from_numpy(pixels).permute(0, 3, 1, 2).unsqueeze(0)
        loggers["wandb"].log_video("eval/video", video, step=frames, fps=fps, format=str(cfg.eval.video_format))
    return path
