"""Tests for torchrl_sail.data: the core checks, the .npz and folder formats, the dim check."""

from __future__ import annotations

import functools
import json
import os
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from tensordict import TensorDict
from torchrl.data import Bounded, Composite, Unbounded

from torchrl_sail import (
    check_demonstration_dims,
    load_demonstrations,
    load_sb_demonstrations,
    save_demonstrations,
)
from torchrl_sail.data.demonstrations import METADATA_FILE, Demonstrations
from torchrl_sail.data.episodes import RETURNS_ATOL, check_finite, check_returns

HOPPER = "expert_data_no_img_Hopper_scores_1500_episodes_{}.npz"
CHEETAH = "expert_data_no_img_HalfCheetah_scores_5600_episodes_{}.npz"

# Verified by hand from episode_starts / episode_returns of each file (numpy 2.4).
HOPPER_10_LENGTHS = [425, 405, 380, 405, 485, 491, 394, 487, 415, 435]
HOPPER_10_RETURNS = [1480.69, 1421.90, 1354.95, 1418.12, 1693.08, 1710.75, 1369.21, 1688.67, 1459.96, 1530.69]
CHEETAH_10_RETURNS = [5797.54, 5768.23, 5804.57, 5633.77, 6007.19, 5819.26, 5710.86, 5847.35, 5815.14, 5887.19]
EXPECTED = {
    HOPPER.format(1): ([425], [1480.69]),
    HOPPER.format(4): (HOPPER_10_LENGTHS[:4], HOPPER_10_RETURNS[:4]),
    HOPPER.format(10): (HOPPER_10_LENGTHS, HOPPER_10_RETURNS),
    CHEETAH.format(1): ([1000], [5646.71]),
    CHEETAH.format(4): ([1000] * 4, [6014.01, 6004.99, 5999.65, 6051.82]),
    CHEETAH.format(10): ([1000] * 10, CHEETAH_10_RETURNS),
}
# (obs dims incl. time feature, action dims)
DIMS = {"Hopper": (12, 3), "HalfCheetah": (18, 6)}

SHIPPED_TEACHERS = Path(__file__).resolve().parents[1] / "examples" / "teachers"
# env: (steps, dense return, obs dims incl. time feature, action dims), made by
# examples/make_teacher.py with seed 0.
SHIPPED = {
    "Hopper-v4": (165, 463.60, 12, 3),
    "Hopper-v5": (179, 444.74, 12, 3),
    "Walker2d-v4": (301, 423.38, 18, 6),
    "Walker2d-v5": (301, 553.18, 18, 6),
    "HalfCheetah-v4": (1000, 1009.32, 18, 6),
    "HalfCheetah-v5": (1000, 1009.32, 18, 6),
    "Swimmer-v4": (1000, 41.86, 9, 2),
    "Swimmer-v5": (1000, 41.86, 9, 2),
}


@functools.cache
def _load(path: str) -> Demonstrations:
    return load_sb_demonstrations(path)


def _loaded(teacher_dir: Path, name: str) -> Demonstrations:
    data, meta = _load(str(teacher_dir / name))
    # callers may mutate; hand out copies of the cached objects
    return Demonstrations(data.clone(), dict(meta))


def _raw(teacher_dir: Path, name: str) -> dict[str, np.ndarray]:
    with np.load(teacher_dir / name, allow_pickle=True) as f:
        return {k: f[k] for k in f.files}


def _make_td(lengths, *, obs_dim=2, fell=True) -> TensorDict:
    """Small synthetic demonstrations: reward = 1, 2, 3, ... over all rows."""
    n = sum(lengths)
    done = torch.zeros(n, 1, dtype=torch.bool)
    done[torch.tensor(lengths).cumsum(0) - 1] = True
    obs = torch.arange(n * obs_dim, dtype=torch.float32).view(n, obs_dim)
    return TensorDict(
        {
            "observation": obs,
            "action": torch.linspace(-1, 1, n).unsqueeze(-1),
            "step_count": torch.cat([torch.arange(k) for k in lengths]).unsqueeze(-1),
            "next": {
                "observation": obs + obs_dim,
                "reward": torch.arange(1, n + 1, dtype=torch.float32).unsqueeze(-1),
                "done": done,
                "terminated": done.clone() if fell else torch.zeros_like(done),
                "truncated": torch.zeros_like(done) if fell else done.clone(),
            },
        },
        batch_size=[n],
    )


def _write_raw(path: Path, td: TensorDict, metadata=None) -> Path:
    """A dataset directory written without save_demonstrations' checks."""
    td.memmap(path)
    (path / METADATA_FILE).write_text(json.dumps(metadata or {}))
    return path


def _write_sb_npz(path, lengths, *, T=1000, time_feature=True, returns=None, drop=()):
    """Writes a file laid out like the SAIL teacher files (object episode_starts)."""
    n = sum(lengths)
    t = np.concatenate([np.arange(k) for k in lengths])
    cols = [np.arange(n, dtype=np.float64), -np.arange(n, dtype=np.float64)]
    if time_feature:
        cols.append(1.0 - t / T)
    obs = np.stack(cols, axis=1).astype(np.float32)
    rewards = np.linspace(0.5, 1.5, n, dtype=np.float32)[:, None]
    starts = np.empty(n, dtype=object)
    starts[0] = True
    for i in range(1, n):
        starts[i] = np.array([t[i] == 0])
    if returns is None:
        bounds = np.cumsum([0] + list(lengths))
        returns = [rewards[a:b].sum(dtype=np.float64) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    arrays = dict(
        obs=obs,
        actions=np.tanh(obs[:, :1] / 10).astype(np.float32),
        rewards=rewards,
        episode_returns=np.asarray(returns, dtype=np.float64),
        episode_starts=starts,
    )
    for key in drop:
        arrays.pop(key)
    np.savez(path, **arrays)
    return obs, rewards


class TestPaperTeacherFiles:
    """The six stable-baselines teacher files of the paper (found by the ``teacher_dir`` fixture)."""

    @pytest.mark.parametrize("name", sorted(EXPECTED))
    def test_episodes_and_returns(self, teacher_dir, name):
        lengths, returns = EXPECTED[name]
        data, meta = _loaded(teacher_dir, name)
        env = "Hopper" if "Hopper" in name else "HalfCheetah"
        obs_dim, act_dim = DIMS[env]

        assert meta["n_episodes"] == len(lengths)
        assert meta["episode_lengths"] == lengths
        assert meta["env_name"] == env
        assert meta["source"] == str(teacher_dir / name)
        np.testing.assert_allclose(meta["episode_returns"], returns, atol=1e-2)
        assert data.batch_size == torch.Size([sum(lengths)])
        assert data["observation"].shape == (sum(lengths), obs_dim)
        assert data["action"].shape == (sum(lengths), act_dim)
        assert data["observation"].dtype == data["action"].dtype == torch.float32
        assert data["step_count"].dtype == torch.int64
        # dense rewards kept: per-episode sums reproduce the recorded returns
        ends = np.cumsum(lengths)
        sums = [
            float(data["next", "reward"][a:b].double().sum()) for a, b in zip(np.r_[0, ends[:-1]], ends, strict=True)
        ]
        np.testing.assert_allclose(sums, returns, atol=2e-2)

    def test_documented_ranges(self, teacher_dir):
        h10 = _loaded(teacher_dir, HOPPER.format(10)).metadata
        assert round(min(h10["episode_returns"]), 1) == 1354.9
        assert round(max(h10["episode_returns"]), 1) == 1710.7
        assert min(h10["episode_lengths"]) == 380 and max(h10["episode_lengths"]) == 491
        c4 = _loaded(teacher_dir, CHEETAH.format(4)).metadata
        assert round(min(c4["episode_returns"]), 1) == 5999.6
        assert round(max(c4["episode_returns"]), 1) == 6051.8
        c10 = _loaded(teacher_dir, CHEETAH.format(10)).metadata
        assert round(min(c10["episode_returns"]), 1) == 5633.8
        assert round(max(c10["episode_returns"]), 1) == 6007.2
        # README: Hopper_4 is the first 4 episodes of Hopper_10
        h4 = _loaded(teacher_dir, HOPPER.format(4)).data
        h10d = _loaded(teacher_dir, HOPPER.format(10)).data
        assert (h4 == h10d[: h4.shape[0]]).all()

    @pytest.mark.parametrize("name", sorted(EXPECTED))
    def test_time_column_next_obs_and_flags(self, teacher_dir, name):
        lengths, _ = EXPECTED[name]
        data, meta = _loaded(teacher_dir, name)
        raw = _raw(teacher_dir, name)
        n = sum(lengths)
        assert meta["time_feature"] is True

        # step_count recomputed independently from the raw episode_starts
        starts = np.array([bool(np.asarray(x).ravel()[0]) for x in raw["episode_starts"]])
        step = np.zeros(n, dtype=np.int64)
        for i in range(1, n):
            step[i] = 0 if starts[i] else step[i - 1] + 1
        assert data["step_count"].squeeze(-1).tolist() == step.tolist()
        torch.testing.assert_close(
            data["observation"][:, -1].double(),
            1.0 - data["step_count"].squeeze(-1).double() / 1000,
            atol=1e-6,
            rtol=0,
        )
        # observations are the file's, bit for bit
        assert torch.equal(data["observation"], torch.from_numpy(raw["obs"]))

        last = np.cumsum(lengths) - 1
        inner = np.setdiff1d(np.arange(n), last)
        assert torch.equal(data["next", "observation"][inner], data["observation"][inner + 1])
        # final next obs: last obs with the time column advanced to 1 - len/1000
        final = data["next", "observation"][last]
        assert torch.equal(final[:, :-1], data["observation"][last, :-1])
        expected_time = torch.tensor([1 - k / 1000 for k in lengths], dtype=torch.float32)
        torch.testing.assert_close(final[:, -1], expected_time, atol=1e-6, rtol=0)

        done = data["next", "done"].squeeze(-1)
        assert torch.nonzero(done).squeeze(-1).tolist() == last.tolist()
        terminated = data["next", "terminated"].squeeze(-1)
        truncated = data["next", "truncated"].squeeze(-1)
        assert torch.equal(done, terminated | truncated)
        if "Hopper" in name:  # the Hopper teacher fell every time
            assert torch.equal(terminated, done) and not truncated.any()
        else:  # HalfCheetah runs into the 1000-step limit
            assert torch.equal(truncated, done) and not terminated.any()
            torch.testing.assert_close(final[:, -1], torch.zeros(len(lengths)))
        assert data["next", "done"].shape == (n, 1)
        assert data["next", "reward"].shape == (n, 1)

    def test_hopper_ignores_file_next_obs(self, teacher_dir):
        name = HOPPER.format(4)
        data, meta = _loaded(teacher_dir, name)
        raw = _raw(teacher_dir, name)
        assert "next_obs" in meta["file_keys"]
        last = np.cumsum(EXPECTED[name][0]) - 1
        inner = np.setdiff1d(np.arange(len(raw["obs"])), last)
        # inside episodes the file's next_obs agrees with obs[t+1] ...
        file_next = torch.from_numpy(raw["next_obs"])
        assert torch.equal(data["next", "observation"][inner], file_next[inner])
        # ... but at episode ends it is a reset observation (time 1.0), which we must not use
        assert np.all(raw["next_obs"][last, -1] == 1.0)
        assert torch.all(data["next", "observation"][last, -1] < 0.7)

    def test_halfcheetah_without_next_obs(self, teacher_dir):
        name = CHEETAH.format(1)
        raw = _raw(teacher_dir, name)
        assert "next_obs" not in raw
        data, meta = _loaded(teacher_dir, name)
        assert "next_obs" not in meta["file_keys"]
        assert torch.equal(data["next", "observation"][:-1], data["observation"][1:])
        assert data["next", "truncated"][-1].item() and not data["next", "terminated"].any()
        # raw actions overshoot +-1 by float32 rounding; loaded ones are clamped, not rescaled
        assert np.abs(raw["actions"]).max() > 1.0
        assert data["action"].abs().max().item() == 1.0
        torch.testing.assert_close(data["action"], torch.from_numpy(raw["actions"]).clamp(-1, 1), atol=0, rtol=0)

    def test_load_demonstrations_dispatches_npz(self, teacher_dir):
        data, meta = load_demonstrations(teacher_dir / HOPPER.format(1))
        ref_data, ref_meta = _loaded(teacher_dir, HOPPER.format(1))
        assert (data == ref_data).all()
        assert meta == ref_meta
        assert meta["format"] == "stable_baselines.ExpertDataset"


class TestShippedTeachers:
    """The sub-optimal teachers of examples/teachers, one directory per env."""

    @pytest.mark.parametrize("env", sorted(SHIPPED))
    def test_load(self, env):
        steps, ret, obs_dim, act_dim = SHIPPED[env]
        data, meta = load_demonstrations(SHIPPED_TEACHERS / env)
        assert meta["env_id"] == env and meta["time_feature"] is True
        assert data.batch_size == (steps,) and meta["episode_lengths"] == [steps]
        assert round(meta["episode_returns"][0], 2) == ret
        assert round(float(data["next", "reward"].double().sum()), 2) == ret
        check_demonstration_dims(data, observation_dim=obs_dim, action_dim=act_dim)
        # a full-length episode was truncated, a shorter one terminated (the walker fell)
        assert data["next", "truncated"][-1].item() == (steps == 1000)
        # as the example loads them (time_feature=True): the column is there, nothing changes
        again, meta = load_demonstrations(SHIPPED_TEACHERS / env, time_feature=True)
        assert (again == data).all() and meta["time_feature_appended"] is False


class TestLoadSBDemonstrations:
    """Synthetic files laid out like the paper's: layout rules and clear errors."""

    def test_two_short_episodes_by_hand(self, tmp_path):
        path = tmp_path / "demo.npz"
        _write_sb_npz(path, [3, 2], T=10)
        data, meta = load_sb_demonstrations(path, max_episode_steps=10)
        # rewards linspace(0.5, 1.5, 5) = 0.5, 0.75, 1.0, 1.25, 1.5
        np.testing.assert_allclose(meta["episode_returns"], [2.25, 2.75])
        assert meta["episode_lengths"] == [3, 2] and meta["n_episodes"] == 2
        assert data["step_count"].squeeze(-1).tolist() == [0, 1, 2, 0, 1]
        assert data["next", "done"].squeeze(-1).tolist() == [False, False, True, False, True]
        # next time column: 1 - (t + 1)/10, also at the episode ends
        torch.testing.assert_close(data["next", "observation"][:, -1], torch.tensor([0.9, 0.8, 0.7, 0.9, 0.8]))
        assert "env_name" not in meta  # not a SAIL-named file

    def test_full_length_episode_is_truncated(self, tmp_path):
        path = tmp_path / "demo.npz"
        _write_sb_npz(path, [4, 2], T=4)
        data, _ = load_sb_demonstrations(path, max_episode_steps=4)
        assert data["next", "truncated"].squeeze(-1).tolist() == [0, 0, 0, 1, 0, 0]
        assert data["next", "terminated"].squeeze(-1).tolist() == [0, 0, 0, 0, 0, 1]

    def test_without_time_feature(self, tmp_path):
        path = tmp_path / "notime.npz"
        obs, _ = _write_sb_npz(path, [3, 2], T=10, time_feature=False)
        data, meta = load_sb_demonstrations(path, max_episode_steps=10)
        assert meta["time_feature"] is False
        # without a time feature the final next obs is the last obs, untouched
        assert torch.equal(data["next", "observation"][[2, 4]], torch.from_numpy(obs[[2, 4]]))

    @pytest.mark.parametrize(
        "kwargs, match",
        [
            (dict(drop=("actions",)), r"bad\.npz: missing key 'actions'"),
            (dict(returns=[1.0, 2.0]), r"bad\.npz: episode 0 has recorded return 1\.0"),
            (dict(returns=[1.0]), r"bad\.npz: 'episode_returns' has 1 entries .* 2 episodes"),
        ],
    )
    def test_bad_content(self, tmp_path, kwargs, match):
        path = tmp_path / "bad.npz"
        _write_sb_npz(path, [4, 3], **kwargs)
        with pytest.raises(ValueError, match=match):
            load_demonstrations(path)

    def test_episode_too_long_and_wrong_time_limit(self, tmp_path):
        path = tmp_path / "long.npz"
        _write_sb_npz(path, [6, 2], T=10)
        with pytest.raises(ValueError, match=r"long\.npz: episode 0 has 6 steps.*steps=5"):
            load_sb_demonstrations(path, max_episode_steps=5)
        # wrong T: the last column is the time feature of T = 10, not 20 (in both detecting modes)
        for time_feature in (None, True):
            with pytest.raises(
                ValueError,
                match=r"long\.npz: the last observation column is the time "
                r"feature 1 - t/T with T=10, not max_episode_steps=20: pass max_episode_steps=10",
            ):
                load_sb_demonstrations(path, max_episode_steps=20, time_feature=time_feature)
        assert load_sb_demonstrations(path, max_episode_steps=20, time_feature=False).metadata["time_feature"] is False

    def test_unreadable_files(self, teacher_dir, tmp_path):
        cut = tmp_path / "cut.npz"
        blob = (teacher_dir / HOPPER.format(1)).read_bytes()
        cut.write_bytes(blob[: len(blob) // 2])
        garbage = tmp_path / "garbage.npz"
        garbage.write_bytes(np.random.default_rng(0).bytes(4096))
        for path in (cut, garbage):
            with pytest.raises(ValueError, match=f"{path.name}: not a readable .npz"):
                load_demonstrations(path)

    def test_pickle_named_npz_is_not_unpickled(self, tmp_path):
        marker = tmp_path / "ran"
        path = tmp_path / "evil.npz"
        # a protocol-0 pickle that runs a shell command when unpickled
        path.write_bytes(b"cos\nsystem\n(S'touch " + str(marker).encode() + b"'\ntR.")
        with pytest.raises(ValueError, match=r"evil\.npz: not a readable \.npz"):
            load_demonstrations(path)
        assert not marker.exists()

    @settings(max_examples=10, deadline=None)
    @given(lengths=st.lists(st.integers(1, 6), min_size=1, max_size=5), T=st.integers(6, 9))
    def test_layout_property(self, tmp_path_factory, lengths, T):
        path = tmp_path_factory.mktemp("prop") / "demo.npz"
        obs, rewards = _write_sb_npz(path, lengths, T=T)
        data, meta = load_demonstrations(path, max_episode_steps=T)
        ends = np.cumsum(lengths) - 1
        assert meta["episode_lengths"] == lengths
        assert torch.nonzero(data["next", "done"].squeeze(-1)).squeeze(-1).tolist() == ends.tolist()
        truncated = [k == T for k in lengths]
        assert data["next", "truncated"][ends].squeeze(-1).tolist() == truncated
        assert data["next", "terminated"][ends].squeeze(-1).tolist() == [not x for x in truncated]
        step = data["step_count"].squeeze(-1)
        torch.testing.assert_close(data["observation"][:, -1], 1 - step.float() / T)
        torch.testing.assert_close(data["next", "observation"][:, -1], 1 - (step.float() + 1) / T)
        assert torch.equal(data["next", "reward"].squeeze(-1), torch.from_numpy(rewards[:, 0]))

        out = path.with_suffix("")
        save_demonstrations(out, Demonstrations(data, meta))
        data2, meta2 = load_demonstrations(out)
        assert meta2 == meta and (data2 == data).all()


class TestSaveDemonstrations:
    """The project's format: tensordict memmap files plus metadata.json, in a directory."""

    def test_round_trip_teacher_file_is_exact(self, teacher_dir, tmp_path):
        demos = _loaded(teacher_dir, HOPPER.format(4))
        path = save_demonstrations(tmp_path / "hopper4", demos)
        assert path == tmp_path / "hopper4"
        data, meta = load_demonstrations(path)
        assert meta == demos.metadata
        assert meta["source"].endswith(HOPPER.format(4))  # provenance kept
        assert set(data.keys(True, True)) == set(demos.data.keys(True, True))
        for key in demos.data.keys(True, True):
            assert data[key].dtype == demos.data[key].dtype, key
            assert torch.equal(data[key], demos.data[key]), key

    def test_layout_and_in_memory_result(self, tmp_path):
        path = save_demonstrations(tmp_path / "demos", _make_td([3, 2]), {"env_id": "Toy-v0"})
        names = {p.relative_to(path).as_posix() for p in path.rglob("*")}
        assert {METADATA_FILE, "meta.json", "observation.memmap", "next/done.memmap"} <= names
        assert json.loads((path / METADATA_FILE).read_text())["env_id"] == "Toy-v0"
        data, _ = load_demonstrations(path)
        assert all(type(v) is torch.Tensor for v in data.values(True, True))
        assert not data.is_locked
        for file in path.rglob("*.memmap"):  # nothing of the result lives in the files
            file.write_bytes(b"\x00" * file.stat().st_size)
        assert torch.equal(data["next", "reward"].squeeze(-1), torch.tensor([1.0, 2, 3, 4, 5]))

    def test_computes_returns_and_lengths(self, tmp_path):
        td = _make_td([3, 2])
        metadata = {"env_id": "Toy-v0", "scale": np.float32(0.5)}
        path = save_demonstrations(tmp_path / "d", td, metadata)
        data, meta = load_demonstrations(path)
        assert meta["episode_lengths"] == [3, 2]
        assert meta["episode_returns"] == [1.0 + 2 + 3, 4.0 + 5]
        assert meta["env_id"] == "Toy-v0" and meta["scale"] == 0.5
        assert meta["source"] == str(path)
        assert (data == td).all()

        # explicit metadata updates a Demonstrations' own; missing lengths are computed
        demos = Demonstrations(td, {"episode_returns": [0.0, 1.0], "note": "a"})
        save_demonstrations(path, demos, {"note": "b"})
        _, meta = load_demonstrations(path)
        assert meta["episode_returns"] == [0.0, 1.0] and meta["episode_lengths"] == [3, 2]
        assert meta["note"] == "b"

    @pytest.mark.parametrize(
        "name, data, metadata, error, match",
        [
            ("d.npz", _make_td([3]), None, ValueError, r"d\.npz: '\.npz' names"),
            ("d", _make_td([3]), {"bad": object()}, TypeError, "JSON"),
            ("d", _make_td([3, 2])[:4], None, ValueError, "last row is not done"),
            ("d", {"observation": torch.zeros(1)}, None, TypeError, "Demonstrations or a Tensor"),
        ],
    )
    def test_rejects_bad_input(self, tmp_path, name, data, metadata, error, match):
        with pytest.raises(error, match=match):
            save_demonstrations(tmp_path / name, data, metadata)
        assert list(tmp_path.iterdir()) == []

    def test_failed_save_keeps_existing_dataset(self, tmp_path, monkeypatch):
        path = tmp_path / "demos"
        good = _make_td([3, 2])
        save_demonstrations(path, good, {"tag": "good"})
        memmap = TensorDict.memmap

        def crashing_memmap(self, prefix, *args, **kwargs):
            memmap(self[:1], prefix, *args, **kwargs)  # some files, then the "crash"
            raise OSError("disk full")

        monkeypatch.setattr(TensorDict, "memmap", crashing_memmap)
        with pytest.raises(OSError, match="disk full"):
            save_demonstrations(path, _make_td([4]), {"tag": "new"})
        monkeypatch.undo()

        assert [p.name for p in tmp_path.iterdir()] == ["demos"]  # no staging dir left
        data, meta = load_demonstrations(path)
        assert meta["tag"] == "good" and (data == good).all()

    def test_failed_swap_restores_existing_dataset(self, tmp_path, monkeypatch):
        path = tmp_path / "demos"
        save_demonstrations(path, _make_td([3, 2]), {"tag": "good"})
        replace = os.replace

        def failing_replace(src, dst):
            if Path(src).name.endswith(".staging"):
                raise OSError("rename failed")
            replace(src, dst)

        monkeypatch.setattr(os, "replace", failing_replace)
        with pytest.raises(OSError, match="rename failed"):
            save_demonstrations(path, _make_td([4]), {"tag": "new"})
        monkeypatch.undo()

        assert [p.name for p in tmp_path.iterdir()] == ["demos"]
        assert load_demonstrations(path).metadata["tag"] == "good"

    def test_save_replaces_existing_dataset(self, tmp_path):
        path = tmp_path / "demos"
        save_demonstrations(path, _make_td([3, 2]), {"tag": "old"})
        save_demonstrations(path, _make_td([4]), {"tag": "new"})
        data, meta = load_demonstrations(path)
        assert meta["tag"] == "new" and meta["episode_lengths"] == [4]
        assert data.batch_size == (4,)
        assert [p.name for p in tmp_path.iterdir()] == ["demos"]


def _without(key):
    td = _make_td([2, 2])
    del td[key]
    return td


def _with(key, value):
    td = _make_td([2, 2])
    td[key] = value
    return td


class TestLoadDemonstrationsErrors:
    """Clear errors, naming the file, for paths and contents that are not demonstrations."""

    @pytest.mark.parametrize("name", ["nope", "nope.npz", "nope.pt"])
    def test_missing_path(self, tmp_path, name):
        with pytest.raises(FileNotFoundError, match=rf"{name}: not demonstrations"):
            load_demonstrations(tmp_path / name)

    def test_missing_npz_file(self, tmp_path):
        with pytest.raises(FileNotFoundError, match=r"nope\.npz"):
            load_sb_demonstrations(tmp_path / "nope.npz")

    @pytest.mark.parametrize("kind", ["file", "directory"])
    def test_wrong_kind_of_path(self, tmp_path, kind):
        path = tmp_path / "old.pt"
        if kind == "file":
            torch.save({"format": "torchrl_sail.demonstrations"}, path)
        else:
            _make_td([2]).memmap(path)  # tensordict files without our metadata.json
        with pytest.raises(ValueError, match=r"old\.pt: not demonstrations; expected ") as err:
            load_demonstrations(path)
        for expected in ("'.npz' file", "directory written by save_demonstrations", "Minari dataset"):
            assert expected in str(err.value)  # every format it reads, in their registration order

    @pytest.mark.parametrize(
        "td, match",
        [
            (_without("action"), r"missing key 'action'"),
            (_without(("next", "truncated")), r"missing key \('next', 'truncated'\)"),
            (_make_td([2, 2]).reshape(2, 2), r"expected a flat, non-empty \[N\] .*\[2, 2\]"),
            (
                _with(("next", "done"), torch.zeros(4, 1)),
                r"\('next', 'done'\) has dtype torch.float32",
            ),
            (
                _with(("next", "reward"), torch.zeros(4)),
                r"\('next', 'reward'\) .* shape \(4,\); expected shape \(4, 1\)",
            ),
            (
                _with(("next", "observation"), torch.zeros(4, 3)),
                r"'observation' \(4, 2\) and \('next', 'observation'\) \(4, 3\) differ",
            ),
            (
                _with(("next", "truncated"), torch.ones(4, 1, dtype=torch.bool)),
                r"\('next', 'done'\) != terminated \| truncated",
            ),
            (_make_td([2, 2])[:3], r"the last row is not done"),
        ],
        ids=[
            "no-action",
            "no-truncated",
            "not-flat",
            "float-done",
            "reward-shape",
            "next-obs-shape",
            "done-flags",
            "last-not-done",
        ],
    )
    def test_invalid_content(self, tmp_path, td, match):
        path = _write_raw(tmp_path / "bad", td)
        with pytest.raises(ValueError, match=rf"bad: {match}"):
            load_demonstrations(path)


class TestCheckDemonstrationDims:
    def test_messages(self, teacher_dir):
        demos = _loaded(teacher_dir, HOPPER.format(1))
        check_demonstration_dims(demos, observation_dim=12, action_dim=3)  # matches

        with pytest.raises(ValueError) as err:
            check_demonstration_dims(demos, observation_dim=11, action_dim=3)
        msg = str(err.value)
        assert "12 dims" in msg and "env has 11" in msg and "enable TimeFeature" in msg
        assert HOPPER.format(1) in msg  # names the file

        no_time = TensorDict({"observation": torch.zeros(2, 11), "action": torch.zeros(2, 3)}, [2])
        with pytest.raises(ValueError, match=r"11 dims, env has 12: disable TimeFeature"):
            check_demonstration_dims(no_time, observation_dim=12)

        with pytest.raises(ValueError, match=r"17.*different env") as err:
            check_demonstration_dims(demos, observation_dim=17, action_dim=3)
        assert "TimeFeature" not in str(err.value)

        with pytest.raises(ValueError, match=r"\(x\.npz\): 'action' has 3 dims, env action has 6"):
            check_demonstration_dims(demos.data, observation_dim=12, action_dim=6, source="x.npz")

        with pytest.raises(TypeError, match="observation_dim"):
            check_demonstration_dims(demos)

    def test_from_env_specs(self, teacher_dir):
        demos = _loaded(teacher_dir, CHEETAH.format(1))
        env = SimpleNamespace(
            observation_spec=Composite(observation=Unbounded(shape=(17,))),
            action_spec=Bounded(-1.0, 1.0, shape=(6,)),
        )
        with pytest.raises(ValueError, match=r"18 dims, env has 17: enable TimeFeature"):
            check_demonstration_dims(demos, env=env)
        env.observation_spec = Composite(observation=Unbounded(shape=(18,)))
        check_demonstration_dims(demos, env=env)
        env.action_spec = Bounded(-1.0, 1.0, shape=(3,))
        with pytest.raises(ValueError, match=r"6 dims, env action has 3"):
            check_demonstration_dims(demos, env=env)


def _strip_time_column(src: Path, dst: Path) -> None:
    """A copy of an authors' file recorded without the time feature: obs (and next_obs) minus the last column."""
    arrays = _raw(src.parent, src.name)
    for key in ("obs", "next_obs"):
        if key in arrays:
            arrays[key] = np.ascontiguousarray(arrays[key][:, :-1])
    np.savez(dst, **arrays)


def _assert_close_td(data, expected, atol=1e-6):
    assert set(data.keys(True, True)) == set(expected.keys(True, True))
    for key in expected.keys(True, True):
        assert data[key].dtype == expected[key].dtype, key
        assert data[key].shape == expected[key].shape, key
        if data[key].is_floating_point():
            torch.testing.assert_close(data[key], expected[key], atol=atol, rtol=0, msg=str(key))
        else:
            assert torch.equal(data[key], expected[key]), key


class TestTimeFeatureComputed:
    """Teachers recorded without the time-feature column get it computed, in every format."""

    @pytest.mark.parametrize("name", [HOPPER.format(4), CHEETAH.format(1)])
    def test_authors_file_without_the_column(self, teacher_dir, tmp_path, name):
        original = _loaded(teacher_dir, name)
        stripped = tmp_path / name  # the same name: the same env_name/nominal_score metadata
        _strip_time_column(teacher_dir / name, stripped)

        # as the example loads a teacher: the column is appended, the result is the original's
        data, meta = load_demonstrations(stripped, max_episode_steps=1000, time_feature=True)
        _assert_close_td(data, original.data, atol=1e-6)
        assert meta["time_feature"] is True and meta["time_feature_appended"] is True
        assert meta["observation_dim"] == original.metadata["observation_dim"]
        assert meta["episode_returns"] == original.metadata["episode_returns"]
        check_demonstration_dims(data, observation_dim=DIMS["Hopper" if "Hopper" in name else "HalfCheetah"][0])

        # detected as absent, and left alone, without time_feature=True
        for time_feature in (None, False):
            data, meta = load_sb_demonstrations(stripped, time_feature=time_feature)
            assert meta["time_feature"] is False and meta["time_feature_appended"] is False
            assert torch.equal(data["observation"], original.data["observation"][:, :-1])

        # a file that has the column is left as it is
        data, meta = load_demonstrations(teacher_dir / name, time_feature=True)
        assert (data == original.data).all() and meta["time_feature_appended"] is False

    @settings(max_examples=10, deadline=None)
    @given(lengths=st.lists(st.integers(1, 6), min_size=1, max_size=4), T=st.integers(6, 9))
    def test_synthetic_npz_with_and_without_the_column(self, tmp_path_factory, lengths, T):
        folder = tmp_path_factory.mktemp("tf")
        _write_sb_npz(folder / "with.npz", lengths, T=T)
        _write_sb_npz(folder / "without.npz", lengths, T=T, time_feature=False)
        expected, _ = load_sb_demonstrations(folder / "with.npz", max_episode_steps=T)
        data, meta = load_sb_demonstrations(folder / "without.npz", max_episode_steps=T, time_feature=True)
        _assert_close_td(data, expected)
        assert meta["time_feature_appended"] is True

    def test_folder_without_the_column(self, tmp_path):
        with_column, _ = load_demonstrations(SHIPPED_TEACHERS / "Hopper-v4")
        plain = with_column.clone()
        for key in ("observation", ("next", "observation")):
            plain[key] = plain[key][:, :-1].contiguous()
        path = save_demonstrations(tmp_path / "plain", plain)
        data, meta = load_demonstrations(path, time_feature=True)
        _assert_close_td(data, with_column)
        assert meta["time_feature"] is True and meta["time_feature_appended"] is True
        # without step_count, t is counted from the done flags
        path = save_demonstrations(tmp_path / "plain2", plain.exclude("step_count"))
        data, _ = load_demonstrations(path, time_feature=True)
        _assert_close_td(data, with_column.exclude("step_count"))
        # by default a folder loads as saved
        data, meta = load_demonstrations(path)
        assert data["observation"].shape[-1] == 11 and "time_feature_appended" not in meta

    def test_folder_with_the_column_of_another_limit(self, tmp_path):
        path = save_demonstrations(tmp_path / "d", load_demonstrations(SHIPPED_TEACHERS / "Hopper-v4").data)
        with pytest.raises(
            ValueError,
            match=r"d: the last observation column is the time feature 1 - t/T "
            r"with T=1000, not max_episode_steps=500",
        ):
            load_demonstrations(path, max_episode_steps=500, time_feature=True)


def _nonfinite_npz(path: Path, key: str, row: int, value: float) -> None:
    _write_sb_npz(path, [4, 3])
    with np.load(path, allow_pickle=True) as f:
        arrays = {k: f[k] for k in f.files}
    arrays[key] = arrays[key].copy()
    arrays[key][row] = value
    np.savez(path, **arrays)


class TestNonFinite:
    """A NaN or infinity is refused by every format, naming the file, the key and the row."""

    @pytest.mark.parametrize(
        "key, row, value, match",
        [
            ("obs", 5, np.nan, r"teacher\.npz: 'obs' has a non-finite value \(nan\) at row 5, column 0"),
            ("obs", 0, np.inf, r"teacher\.npz: 'obs' has a non-finite value \(inf\) at row 0"),
            ("actions", 2, -np.inf, r"teacher\.npz: 'actions' has a non-finite value \(-inf\) at row 2"),
            ("rewards", 6, np.nan, r"teacher\.npz: 'rewards' has a non-finite value \(nan\) at row 6"),
            (
                "episode_returns",
                1,
                np.nan,
                r"teacher\.npz: 'episode_returns' has a non-finite value \(nan\) "
                r"at row 1",
            ),
        ],
    )
    def test_npz(self, tmp_path, key, row, value, match):
        path = tmp_path / "teacher.npz"
        _nonfinite_npz(path, key, row, value)
        for time_feature in (None, True, False):
            with pytest.raises(ValueError, match=match):
                load_demonstrations(path, time_feature=time_feature)

    def test_nan_in_an_authors_file(self, teacher_dir, tmp_path):
        arrays = _raw(teacher_dir, HOPPER.format(1))
        arrays["obs"] = arrays["obs"].copy()
        arrays["obs"][123, 4] = np.nan
        path = tmp_path / HOPPER.format(1)
        np.savez(path, **arrays)
        with pytest.raises(
            ValueError,
            match=rf"{HOPPER.format(1)}: 'obs' has a non-finite value \(nan\) at "
            r"row 123, column 4",
        ):
            load_demonstrations(path, time_feature=True)

    @pytest.mark.parametrize("key", ["observation", ("next", "observation"), ("next", "reward"), "action"])
    def test_folder(self, tmp_path, key):
        td = _make_td([2, 2])
        td[key][3] = float("nan")
        path = _write_raw(tmp_path / "bad", td)
        with pytest.raises(ValueError, match=rf"bad: {re.escape(repr(key))} has a non-finite value \(nan\) at row 3"):
            load_demonstrations(path)
        with pytest.raises(ValueError, match=r"data to save to .*: .* non-finite value \(nan\) at row 3"):
            save_demonstrations(tmp_path / "out", td)
        assert not (tmp_path / "out").exists()

    def test_check_finite_and_check_returns(self):
        check_finite({"flag": np.array([True]), "steps": torch.arange(3)}, "x")  # not floats: skipped
        with pytest.raises(ValueError, match=r"x: 'r' has a non-finite value \(nan\) at episode 1"):
            check_finite({"r": np.array([0.0, np.nan])}, "x", row_name="episode")
        check_returns([1.0 + RETURNS_ATOL / 2], [1.0], [1], "x")  # within the tolerance
        with pytest.raises(ValueError, match=r"x: 'recorded return' has a non-finite value \(inf\) at episode 0"):
            check_returns([np.inf], [1.0], [1], "x")
        with pytest.raises(ValueError, match="episode 0 has recorded return 1.010000 but its rewards sum to 1.000000"):
            check_returns([1.01], [1.0], [1], "x")


class TestEnvKwargHints:
    """check_demonstration_dims names the gymnasium.make kwarg (config key env.kwargs) a mismatch points to."""

    @staticmethod
    def _demos(obs_dim, act_dim=8):
        return TensorDict({"observation": torch.zeros(3, obs_dim), "action": torch.zeros(3, act_dim)}, [3])

    def test_ant_contact_forces(self):
        # Ant-v4: 27 dims, 111 with use_contact_forces=True; +1 each for the time feature
        with pytest.raises(ValueError) as err:
            check_demonstration_dims(self._demos(112), observation_dim=28, env_name="Ant-v4", source="ant.npz")
        msg = str(err.value)
        assert msg.startswith("teacher data (ant.npz): 'observation' has 112 dims, env has 28: an env kwarg")
        assert "use_contact_forces=True" in msg and "env.kwargs.use_contact_forces=true" in msg
        with pytest.raises(
            ValueError,
            match=r"probably has it and the teacher did not; make the env without it "
            r"\(config key env.kwargs: env.kwargs.use_contact_forces=false\)",
        ):
            check_demonstration_dims(self._demos(28), observation_dim=112, env_name="Ant-v4")

    def test_env_name_from_a_torchrl_env(self):
        env = SimpleNamespace(
            observation_spec=Composite(observation=Unbounded(shape=(28,))),
            action_spec=Bounded(-1.0, 1.0, shape=(8,)),
            base_env=SimpleNamespace(env_name="Ant-v4"),
        )
        with pytest.raises(ValueError, match=r"env\.kwargs\.use_contact_forces=true"):
            check_demonstration_dims(self._demos(112), env=env)

    def test_one_dim_names_time_feature_first_then_the_kwarg(self):
        with pytest.raises(ValueError) as err:
            check_demonstration_dims(self._demos(13, 3), observation_dim=12, env_name="Hopper-v4")
        msg = str(err.value)
        assert "enable TimeFeature" in msg
        assert msg.index("TimeFeature") < msg.index("exclude_current_positions_from_observation=False")
        assert "env.kwargs.exclude_current_positions_from_observation=false" in msg

    def test_what_a_torchrl_env_says_about_the_time_feature(self):
        from torchrl_sail import make_sail_env

        with_feature, without = make_sail_env("Hopper-v4"), make_sail_env("Hopper-v4", time_feature=False)
        # one column too many for an env that already appends the feature: not "enable TimeFeature"
        with pytest.raises(ValueError) as err:
            check_demonstration_dims(self._demos(13, 3), env=with_feature)
        assert "TimeFeature" not in str(err.value)
        assert "env.kwargs.exclude_current_positions_from_observation=false" in str(err.value)
        with pytest.raises(ValueError, match=r"12 dims, env has 11: enable TimeFeature"):
            check_demonstration_dims(self._demos(12, 3), env=without)
        with pytest.raises(ValueError, match=r"11 dims, env has 12: disable TimeFeature .* time_feature=True"):
            check_demonstration_dims(self._demos(11, 3), env=with_feature)
        with pytest.raises(ValueError) as err:  # one column too few for an env without the feature
            check_demonstration_dims(self._demos(10, 3), env=without)
        assert "TimeFeature" not in str(err.value)
        assert "env.kwargs.exclude_current_positions_from_observation=true" in str(err.value)

    def test_unknown_difference_mentions_env_kwargs(self):
        with pytest.raises(ValueError) as err:
            check_demonstration_dims(self._demos(40), observation_dim=28, env_name="Ant-v4")
        msg = str(err.value)
        assert "different env" in msg and "env.kwargs" in msg and "TimeFeature" not in msg
        with pytest.raises(ValueError, match="env.kwargs"):  # no env id at all
            check_demonstration_dims(self._demos(40), observation_dim=28)
