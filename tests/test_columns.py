"""Teacher observation columns: which the env does not reproduce (named before training), and the
columns kept or dropped (``torchrl_sail.data.columns`` and ``teacher.*_columns``)."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from torchrl_sail.data import keep_columns, parse_columns, unreproduced_columns
from torchrl_sail.data.columns import column_ranges

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))


@pytest.mark.parametrize(
    ("spec", "expected"), [("3", [3]), ("27-29,5", [5, 27, 28, 29]), (" 0-1 , 1-2 ", [0, 1, 2]), ("111", [111])]
)
def test_parse_columns(spec, expected):
    assert parse_columns(spec, width=112) == expected
    assert parse_columns(column_ranges(expected), width=112) == expected


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("27-112", r"teacher.drop_columns='27-112': '27-112' is not a range of columns 0-111 \(the teacher's 112\)"),
        ("5-3", r"'5-3' is not a range of columns"),
        ("a", r"'a' is not an index or a range like 27-110"),
        ("1,,2", r"'' is not an index"),
    ],
)
def test_parse_columns_names_the_key_and_the_bad_item(spec, match):
    with pytest.raises(ValueError, match=match):
        parse_columns(spec, width=112, key="teacher.drop_columns")


def test_keep_columns_applies_to_both_observations_and_leaves_the_input():
    obs = torch.arange(12.0).reshape(3, 4)
    data = TensorDict({"observation": obs, "action": torch.zeros(3, 1), "next": {"observation": obs + 100}}, [3])
    kept = keep_columns(data, [0, 3])
    assert kept["observation"].tolist() == [[0, 3], [4, 7], [8, 11]]
    assert kept["next", "observation"].tolist() == [[100, 103], [104, 107], [108, 111]]
    assert data["observation"].shape == (3, 4) and data["next", "observation"].shape == (3, 4)


def test_unreproduced_columns_by_hand():
    teacher = torch.tensor([[0.0, 1.0, 500.0, 7.0, 12.0], [0.0, 2.0, 501.0, 7.0, 20.0]])
    env = torch.tensor([[0.3, 1.5, 0.0, 7.0, 0.0], [-0.2, 2.5, 1.0, 7.0, 1.0]])
    found = unreproduced_columns(teacher, env)
    # 0: constant 0 in the teacher, -0.2..0.3 in the env; 2: 499 above an env range of 1 (> 10 x 1);
    # 1: overlaps; 3: constant in both; 4: its nearest value, 12, is 11 env ranges above the env's 1
    assert [(c["column"], c["kind"]) for c in found] == [(0, "constant"), (2, "outside"), (4, "outside")]
    assert found[0]["teacher"] == (0.0, 0.0) and found[0]["env"] == pytest.approx((-0.2, 0.3))
    assert unreproduced_columns(teacher, env, far=20.0)[-1]["column"] == 2  # 11 < 20 ranges: column 4 is not


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_unreproduced_columns_takes_demonstrations_on_another_device_than_the_env():
    # with device=cuda the demonstrations are on the GPU and the check's rollout on the CPU
    teacher = torch.tensor([[0.0, 1.0, 500.0], [0.0, 2.0, 501.0]], device="cuda")
    env = torch.tensor([[0.3, 1.5, 0.0], [-0.2, 2.5, 1.0]])
    found = unreproduced_columns(teacher, env, env_episodes=torch.tensor([0, 0], device="cuda"))
    assert [(c["column"], c["kind"]) for c in found] == [(0, "constant"), (2, "outside")]


def _hopper_teacher(path, constant_column=5, steps=50):
    """A Hopper-v4 teacher file in the paper's format, one column held at 0.0."""
    rng = np.random.default_rng(0)
    t = np.arange(steps)
    obs = np.concatenate([rng.normal(size=(steps, 11)), (1 - t / 1000)[:, None]], axis=1).astype("float32")
    obs[:, constant_column] = 0.0
    starts = np.empty(steps, dtype=object)
    starts[:] = [True] + [np.array([False])] * (steps - 1)
    np.savez(
        path,
        obs=obs,
        actions=rng.uniform(-1, 1, size=(steps, 3)).astype("float32"),
        rewards=np.ones((steps, 1), "float32"),
        episode_returns=np.array([float(steps)]),
        episode_starts=starts,
    )
    return path


def _make(*overrides):
    from test_config import make

    return make("env=Hopper-v4", *overrides)


def test_make_teacher_names_the_columns_the_env_does_not_reproduce(tmp_path):
    from utils import make_env, make_teacher

    path = _hopper_teacher(tmp_path / "teacher.npz")
    cfg = _make(f"teacher.path={path}")
    env = make_env(cfg, 0)
    with pytest.warns(UserWarning, match=r"1 of its 12 observation columns are not what Hopper-v4 produces") as record:
        make_teacher(cfg, env)
    message = str(record[0].message)
    assert "columns 5: constant in the teacher, varying in the env (column 5: teacher 0 to 0" in message
    assert "teacher.drop_columns='5' " in message
    with pytest.raises(ValueError, match=r"1 of its 12 observation columns"):
        make_teacher(_make(f"teacher.path={path}", "teacher.column_check=error"), env)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        make_teacher(_make(f"teacher.path={path}", "teacher.column_check=off"), env)


def test_dropped_columns_must_match_the_env(tmp_path):
    from utils import make_env, make_teacher

    path = _hopper_teacher(tmp_path / "teacher.npz")
    cfg = _make(f"teacher.path={path}", "teacher.drop_columns=5", "teacher.column_check=off")
    with pytest.raises(ValueError, match=r"'observation' has 11 dims, env has 12"):
        make_teacher(cfg, make_env(cfg, 0))
    cfg = _make(f"teacher.path={path}", "teacher.keep_columns='0-4,6-11'")  # the same 11 of 12 columns
    with pytest.raises(ValueError, match=r"'observation' has 11 dims, env has 12"):
        make_teacher(cfg, make_env(cfg, 0))


def test_keep_and_drop_together_are_refused():
    from config_schema import check_config

    with pytest.raises(ValueError, match=r"teacher.drop_columns='5': and teacher.keep_columns are two ways"):
        check_config(_make("teacher.drop_columns=5", "teacher.keep_columns=0-4"))


def test_the_column_check_leaves_the_runs_random_stream_as_it_was(tmp_path):
    from utils import check_teacher_columns

    path = _hopper_teacher(tmp_path / "teacher.npz", constant_column=0)
    cfg = _make(f"teacher.path={path}")
    torch.manual_seed(7)
    expected = torch.rand(3)
    torch.manual_seed(7)
    with pytest.warns(UserWarning):
        check_teacher_columns(cfg, torch.zeros(5, 12), path)
    assert torch.equal(torch.rand(3), expected)


def test_the_time_feature_column_is_kept(tmp_path):
    from utils import make_env, make_teacher

    path = _hopper_teacher(tmp_path / "teacher.npz")
    for setting, spec in (("drop_columns", "5-11"), ("keep_columns", "0-10")):
        cfg = _make(f"teacher.path={path}", f"teacher.{setting}={spec}", "teacher.column_check=off")
        with pytest.raises(ValueError, match=rf"teacher.{setting}='{spec}' leaves out column 11, the time feature"):
            make_teacher(cfg, make_env(cfg, 0))


def _ant_teacher(path, steps=60):
    """A file named as the authors' Ant teacher, in its layout: Ant-v4's 27 columns, its 84 contact-force
    columns (27-110) at 0.0 in every row, as mujoco-py 2.x recorded them, and the time feature."""
    rng = np.random.default_rng(0)
    t = np.arange(steps)
    obs = np.concatenate([rng.normal(size=(steps, 27)), np.zeros((steps, 84)), (1 - t / 1000)[:, None]], axis=1)
    starts = np.empty(steps, dtype=object)
    starts[:] = [True] + [np.array([False])] * (steps - 1)
    np.savez(
        path,
        obs=obs.astype("float32"),
        actions=rng.uniform(-1, 1, size=(steps, 8)).astype("float32"),
        rewards=np.ones((steps, 1), "float32"),
        episode_returns=np.array([float(steps)]),
        episode_starts=starts,
    )
    return path


def test_the_ant_files_check_names_the_contact_forces_and_the_settings_that_drop_them(tmp_path):
    """The 84 contact-force columns are named, those a random rollout leaves still among them too, and
    the choice given is the one that loads: columns 27-110 dropped with the env's contact forces off."""
    from test_config import make
    from utils import make_env, make_teacher

    path = _ant_teacher(tmp_path / "expert_data_no_img_Ant_scores_1200_episodes_1.npz")
    cfg = make("env=Ant-v4", f"teacher.path={path}")
    with pytest.warns(UserWarning, match=r"of its 112 observation columns are not what Ant-v4 produces") as record:
        make_teacher(cfg, make_env(cfg, 0))
    message = str(record[0].message)
    named = [line.split(":")[0].split("columns ")[1] for line in message.splitlines() if line.startswith("  columns ")]
    assert sorted(c for spec in named for c in parse_columns(spec, width=112)) == list(range(27, 111))
    assert (
        "train on the columns the env reproduces: teacher.drop_columns=27-110 env.kwargs.use_contact_forces=false."
        in message
    )
    # that choice loads, and the check has nothing left to say
    cfg = make(
        "env=Ant-v4", f"teacher.path={path}", "teacher.drop_columns=27-110", "env.kwargs.use_contact_forces=false"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        buffer, _, _ = make_teacher(cfg, make_env(cfg, 0))
    assert buffer.sample(4)["observation"].shape == (4, 28)
