"""``make_sail_env``'s gymnasium arguments: ``env_kwargs`` and the camera videos render from."""

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
