"""``make_sail_env``'s gymnasium arguments: ``env_kwargs``, the camera videos render from, and a batched env."""

from __future__ import annotations

import mujoco
import pytest

from torchrl_sail import make_sail_env


def renderer(env):
    return env.base_env._env.unwrapped.mujoco_renderer


def test_env_kwargs_reach_gymnasium_make():
    # Hopper's observation without / with the torso's x position, plus the time feature
    assert make_sail_env("Hopper-v4").observation_spec["observation"].shape[-1] == 12
    env = make_sail_env("Hopper-v4", env_kwargs={"exclude_current_positions_from_observation": False})
    assert env.observation_spec["observation"].shape[-1] == 13
    assert env.rollout(2)["observation"].shape == (2, 13)


def test_unknown_env_kwarg_names_it():
    with pytest.raises(ValueError, match=r"gymnasium.make\('Hopper-v4'\) rejects env_kwargs=\{'legs': 3\}"):
        make_sail_env("Hopper-v4", env_kwargs={"legs": 3})


@pytest.mark.parametrize("name", ["Hopper-v4", "Walker2d-v4", "HalfCheetah-v4", "Swimmer-v4"])
def test_videos_follow_the_body(name):
    # the model's "track" camera (mode trackcom) rather than gymnasium's fixed free camera
    view = renderer(make_sail_env(name, render_size=(64, 48)))
    track = mujoco.mj_name2id(view.model, mujoco.mjtObj.mjOBJ_CAMERA, "track")
    assert track >= 0 and view.camera_id == track
    assert view.model.cam_mode[track] == mujoco.mjtCamLight.mjCAMLIGHT_TRACKCOM
    assert renderer(make_sail_env(name, render_size=(64, 48), render_camera=None)).camera_id == -1


def test_num_envs_batches_the_stack_env_i_seeded_seed_plus_i_strides():
    """num_envs=3: one batched env whose env i starts where one env seeded 7 + i * SEED_STRIDE does,
    with the time feature per env; with render_size, or below 1, refused."""
    import torch

    from torchrl_sail.envs import SEED_STRIDE

    batched = make_sail_env("Hopper-v4", num_envs=3)
    batched.set_seed(7)
    assert batched.batch_size == torch.Size([3]) and batched.action_spec.shape == torch.Size([3, 3])
    rollout = batched.rollout(3)
    assert rollout["observation"][:, :, -1].tolist() == [[1.0, 0.9990000128746033, 0.9980000257492065]] * 3
    for i in range(3):
        alone = make_sail_env("Hopper-v4")
        alone.set_seed(7 + i * SEED_STRIDE)
        assert torch.equal(alone.reset()["observation"], rollout["observation"][i, 0])
    assert len({tuple(rollout["observation"][i, 0].tolist()) for i in range(3)}) == 3  # three start states
    with pytest.raises(ValueError, match=r"num_envs=2: must be 1 or more, and 1 with render_size=\(64, 64\)"):
        make_sail_env("Hopper-v4", num_envs=2, render_size=(64, 64))
    with pytest.raises(ValueError, match="num_envs=0"):
        make_sail_env("Hopper-v4", num_envs=0)
