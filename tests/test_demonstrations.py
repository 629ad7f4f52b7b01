"""Tests for torchrl_sail.data.demonstrations (teacher files, own format, dim check)."""
from __future__ import annotations

import functools
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from hypothesis import given, settings, strategies as st
from tensordict import TensorDict
from torchrl.data import Bounded, Composite, Unbounded

from torchrl_sail import (
    check_demonstration_dims,
    load_demonstrations,
    load_sb_demonstrations,
    save_demonstrations,
)
from torchrl_sail.data.demonstrations import Demonstrations

HOPPER = "expert_data_no_img_Hopper_scores_1500_episodes_{}.npz"
CHEETAH = "expert_data_no_img_HalfCheetah_scores_5600_episodes_{}.npz"

# Verified by hand from episode_starts / episode_returns of each file (numpy 2.4).
HOPPER_10_LENGTHS = [425, 405, 380, 405, 485, 491, 394, 487, 415, 435]
HOPPER_10_RETURNS = [
    1480.69, 1421.90, 1354.95, 1418.12, 1693.08, 1710.75, 1369.21, 1688.67, 1459.96, 1530.69
]
CHEETAH_10_RETURNS = [
    5797.54, 5768.23, 5804.57, 5633.77, 6007.19, 5819.26, 5710.86, 5847.35, 5815.14, 5887.19
]
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


@functools.lru_cache(maxsize=None)
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
    return TensorDict(
        {
            "observation": torch.arange(n * obs_dim, dtype=torch.float32).view(n, obs_dim),
            "action": torch.linspace(-1, 1, n).unsqueeze(-1),
            "step_count": torch.cat([torch.arange(k) for k in lengths]).unsqueeze(-1),
            "next": {
                "observation": torch.arange(n * obs_dim, dtype=torch.float32).view(n, obs_dim)
                + obs_dim,
                "reward": torch.arange(1, n + 1, dtype=torch.float32).unsqueeze(-1),
                "done": done,
                "terminated": done.clone() if fell else torch.zeros_like(done),
                "truncated": torch.zeros_like(done) if fell else done.clone(),
            },
        },
        batch_size=[n],
    )


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
        returns = [rewards[a:b].sum(dtype=np.float64) for a, b in zip(bounds[:-1], bounds[1:])]
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


# ---------------------------------------------------------------- the six teacher files
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_teacher_file_episodes(teacher_dir, name):
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
        float(data["next", "reward"][a:b].double().sum())
        for a, b in zip(np.r_[0, ends[:-1]], ends)
    ]
    np.testing.assert_allclose(sums, returns, atol=2e-2)
    # returns against the README ranges
    assert min(meta["episode_returns"]) >= min(returns) - 0.01
    assert max(meta["episode_returns"]) <= max(returns) + 0.01


def test_documented_ranges(teacher_dir):
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
def test_time_column_next_obs_and_flags(teacher_dir, name):
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


def test_hopper_ignores_file_next_obs(teacher_dir):
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


def test_halfcheetah_without_next_obs(teacher_dir):
    name = CHEETAH.format(1)
    raw = _raw(teacher_dir, name)
    assert "next_obs" not in raw
    data, meta = _loaded(teacher_dir, name)
    assert "next_obs" not in meta["file_keys"]
    assert torch.equal(data["next", "observation"][:-1], data["observation"][1:])
    assert data["next", "truncated"][-1].item() and not data["next", "terminated"].any()
    # the raw actions overshoot +-1 by float32 rounding; loaded ones are clamped, not rescaled
    assert np.abs(raw["actions"]).max() > 1.0
    assert data["action"].abs().max().item() == 1.0
    torch.testing.assert_close(
        data["action"], torch.from_numpy(raw["actions"]).clamp(-1, 1), atol=0, rtol=0
    )


def test_load_demonstrations_dispatches_npz(teacher_dir):
    data, meta = load_demonstrations(teacher_dir / HOPPER.format(1))
    ref_data, ref_meta = _loaded(teacher_dir, HOPPER.format(1))
    assert (data == ref_data).all()
    assert meta == ref_meta
    assert meta["format"] == "stable_baselines.ExpertDataset"


# ---------------------------------------------------------------- own format
def test_round_trip_teacher_file(teacher_dir, tmp_path):
    demos = _loaded(teacher_dir, HOPPER.format(4))
    path = save_demonstrations(tmp_path / "hopper4.pt", demos)
    assert path == tmp_path / "hopper4.pt"
    raw = torch.load(path, weights_only=True)
    assert raw["format"] == "torchrl_sail.demonstrations" and raw["version"] == 1
    data, meta = load_demonstrations(path)
    assert meta == demos.metadata
    assert meta["source"].endswith(HOPPER.format(4))  # provenance kept
    assert set(data.keys(True, True)) == set(demos.data.keys(True, True))
    for key in demos.data.keys(True, True):
        assert data[key].dtype == demos.data[key].dtype, key
        assert torch.equal(data[key], demos.data[key]), key


def test_save_recomputes_returns_and_lengths(tmp_path):
    td = _make_td([3, 2])
    path = tmp_path / "d.pt"
    save_demonstrations(path, td, {"env_id": "Toy-v0", "scale": np.float32(0.5)})
    data, meta = load_demonstrations(path)
    assert meta["episode_lengths"] == [3, 2]
    assert meta["episode_returns"] == [1.0 + 2 + 3, 4.0 + 5]
    assert meta["env_id"] == "Toy-v0" and meta["scale"] == 0.5
    assert meta["source"] == str(path)
    assert meta["format"] == "torchrl_sail.demonstrations"
    assert (data == td).all()

    # explicit metadata overrides a Demonstrations' own
    save_demonstrations(path, Demonstrations(td, {"episode_returns": [0.0, 1.0]}), {"note": "x"})
    _, meta = load_demonstrations(path)
    assert meta["episode_returns"] == [0.0, 1.0] and meta["episode_lengths"] == [3, 2]
    assert meta["note"] == "x"


def test_save_rejects_bad_input(tmp_path):
    td = _make_td([3])
    with pytest.raises(ValueError, match=r"\.npz"):
        save_demonstrations(tmp_path / "d.npz", td)
    with pytest.raises(TypeError, match="JSON"):
        save_demonstrations(tmp_path / "d.pt", td, {"bad": object()})
    with pytest.raises(ValueError, match="last row is not done"):
        save_demonstrations(tmp_path / "d.pt", _make_td([3, 2])[:4])
    with pytest.raises(TypeError, match="Demonstrations or a TensorDict"):
        save_demonstrations(tmp_path / "d.pt", {"observation": torch.zeros(1)})
    assert list(tmp_path.iterdir()) == []


def test_atomic_write_keeps_existing_file(tmp_path, monkeypatch):
    path = tmp_path / "demos.pt"
    good = _make_td([3, 2])
    save_demonstrations(path, good, {"tag": "good"})
    before = path.read_bytes()

    def crashing_save(obj, f, *args, **kwargs):
        f.write(b"PK\x03\x04 half a file")  # partial content, then the "crash"
        raise OSError("disk full")

    monkeypatch.setattr(torch, "save", crashing_save)
    with pytest.raises(OSError, match="disk full"):
        save_demonstrations(path, _make_td([4]), {"tag": "new"})
    monkeypatch.undo()

    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demos.pt"]  # no temp file left
    data, meta = load_demonstrations(path)
    assert meta["tag"] == "good" and (data == good).all()

    # a successful save replaces the file
    save_demonstrations(path, _make_td([4]), {"tag": "new"})
    assert load_demonstrations(path).metadata["tag"] == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demos.pt"]


# ---------------------------------------------------------------- bad files
def test_missing_file(tmp_path):
    path = tmp_path / "nope.npz"
    with pytest.raises(FileNotFoundError, match="nope.npz"):
        load_demonstrations(path)
    with pytest.raises(FileNotFoundError, match="nope.npz"):
        load_sb_demonstrations(path)


@pytest.mark.parametrize("suffix", [".npz", ".pt", ".bin"])
def test_random_bytes(tmp_path, suffix):
    path = tmp_path / f"garbage{suffix}"
    path.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(ValueError, match=r"garbage.*not a zip"):
        load_demonstrations(path)


def test_truncated_files(teacher_dir, tmp_path):
    blob = (teacher_dir / HOPPER.format(1)).read_bytes()
    path = tmp_path / "cut.npz"
    path.write_bytes(blob[: len(blob) // 2])
    with pytest.raises(ValueError, match=r"cut\.npz.*not a zip"):
        load_demonstrations(path)
    with pytest.raises(ValueError, match=r"cut\.npz.*not a zip"):
        load_sb_demonstrations(path)

    good = tmp_path / "good.pt"
    save_demonstrations(good, _make_td([3]))
    blob = good.read_bytes()
    cut = tmp_path / "cut.pt"
    cut.write_bytes(blob[: len(blob) - 200])
    with pytest.raises(ValueError, match=r"cut\.pt"):
        load_demonstrations(cut)


def test_corrupt_npz_member(tmp_path):
    """A zip whose central directory is intact but whose member data is damaged."""
    path = tmp_path / "damaged.npz"
    _write_sb_npz(path, [5])
    blob = bytearray(path.read_bytes())
    start = blob.index(b"\x93NUMPY")  # first array header
    blob[start : start + 40] = b"\x00" * 40
    path.write_bytes(bytes(blob))
    with pytest.raises(ValueError, match=r"damaged\.npz"):
        load_demonstrations(path)


def test_wrong_format_tag_and_version(tmp_path):
    path = tmp_path / "other.pt"
    torch.save({"format": "someone.else", "version": 1, "metadata": {}, "data": {}}, path)
    with pytest.raises(ValueError, match=r"other\.pt.*format tag 'someone\.else'"):
        load_demonstrations(path)
    torch.save({"format": "torchrl_sail.demonstrations", "version": 99, "metadata": {}}, path)
    with pytest.raises(ValueError, match=r"other\.pt.*version 99"):
        load_demonstrations(path)
    torch.save(torch.zeros(3), path)
    with pytest.raises(ValueError, match=r"other\.pt.*expected a dict"):
        load_demonstrations(path)


def test_pickled_objects_rejected(tmp_path):
    path = tmp_path / "pickled.pt"
    torch.save({"format": "torchrl_sail.demonstrations", "version": 1, "x": Path("a")}, path)
    with pytest.raises(ValueError, match=r"pickled\.pt.*weights_only"):
        load_demonstrations(path)


def _payload(td, **meta):
    return {
        "format": "torchrl_sail.demonstrations",
        "version": 1,
        "metadata": meta,
        "data": td.to_dict(),
    }


def test_invalid_project_content(tmp_path):
    path = tmp_path / "bad.pt"
    td = _make_td([2, 2])

    payload = _payload(td)
    del payload["data"]["action"]
    torch.save(payload, path)
    with pytest.raises(ValueError, match=r"bad\.pt.*missing key 'action'"):
        load_demonstrations(path)

    payload = _payload(td)
    payload["data"]["next"]["reward"] = torch.zeros(3, 1)
    torch.save(payload, path)
    with pytest.raises(ValueError, match=r"bad\.pt.*inconsistent batch sizes"):
        load_demonstrations(path)

    undone = td.clone()
    undone["next", "done"][-1] = False
    undone["next", "terminated"][-1] = False
    torch.save(_payload(undone), path)
    with pytest.raises(ValueError, match=r"bad\.pt.*last row is not done"):
        load_demonstrations(path)

    never = td.clone()
    for key in ("done", "terminated"):
        never["next", key].zero_()
    torch.save(_payload(never), path)
    with pytest.raises(ValueError, match=r"bad\.pt.*no \('next', 'done'\)"):
        load_demonstrations(path)

    torch.save(_payload(td, episode_lengths=[3, 1, 0]), path)
    with pytest.raises(ValueError, match=r"bad\.pt.*episode_lengths"):
        load_demonstrations(path)

    payload = _payload(td)
    del payload["metadata"]
    torch.save(payload, path)
    with pytest.raises(ValueError, match=r"bad\.pt.*missing key 'metadata'"):
        load_demonstrations(path)


def test_sb_missing_key_and_bad_returns(tmp_path):
    path = tmp_path / "noact.npz"
    _write_sb_npz(path, [4, 3], drop=("actions",))
    with pytest.raises(ValueError, match=r"noact\.npz.*missing key 'actions'"):
        load_demonstrations(path)

    path = tmp_path / "badret.npz"
    _write_sb_npz(path, [4, 3], returns=[1.0, 2.0])
    with pytest.raises(ValueError, match=r"badret\.npz.*episode 0 .*recorded return 1\.0"):
        load_demonstrations(path)

    path = tmp_path / "nret.npz"
    _write_sb_npz(path, [4, 3], returns=[1.0])
    with pytest.raises(ValueError, match=r"nret\.npz.*1 entries.*2 episodes"):
        load_demonstrations(path)


def test_sb_episode_too_long_and_time_feature(tmp_path):
    path = tmp_path / "long.npz"
    _write_sb_npz(path, [6, 2], T=10)
    with pytest.raises(ValueError, match=r"long\.npz.*episode 0 has 6 steps.*steps=5"):
        load_sb_demonstrations(path, max_episode_steps=5)
    # wrong T: the last column no longer matches 1 - t/T
    with pytest.raises(ValueError, match=r"long\.npz.*not the time feature"):
        load_sb_demonstrations(path, max_episode_steps=20, time_feature=True)

    path = tmp_path / "notime.npz"
    obs, _ = _write_sb_npz(path, [3, 2], T=10, time_feature=False)
    data, meta = load_sb_demonstrations(path, max_episode_steps=10)
    assert meta["time_feature"] is False
    # without a time feature the final next obs is the last obs, untouched
    assert torch.equal(data["next", "observation"][[2, 4]], torch.from_numpy(obs[[2, 4]]))
    assert "env_name" not in meta  # not a SAIL-named file


@settings(max_examples=15, deadline=None)
@given(
    lengths=st.lists(st.integers(1, 6), min_size=1, max_size=5),
    T=st.integers(6, 9),
)
def test_sb_layout_property(tmp_path_factory, lengths, T):
    path = tmp_path_factory.mktemp("prop") / "demo.npz"
    obs, rewards = _write_sb_npz(path, lengths, T=T)
    data, meta = load_demonstrations(path, max_episode_steps=T)
    n = sum(lengths)
    ends = np.cumsum(lengths) - 1
    assert meta["episode_lengths"] == lengths
    np.testing.assert_allclose(
        meta["episode_returns"],
        [rewards[e - k + 1 : e + 1].sum(dtype=np.float64) for e, k in zip(ends, lengths)],
        rtol=1e-6,
    )
    assert torch.nonzero(data["next", "done"].squeeze(-1)).squeeze(-1).tolist() == ends.tolist()
    truncated = [k == T for k in lengths]
    assert data["next", "truncated"][ends].squeeze(-1).tolist() == truncated
    assert data["next", "terminated"][ends].squeeze(-1).tolist() == [not x for x in truncated]
    step = data["step_count"].squeeze(-1)
    torch.testing.assert_close(data["observation"][:, -1], 1 - step.float() / T)
    # next time column is always 1 - (t + 1)/T, inside episodes and at their ends
    torch.testing.assert_close(data["next", "observation"][:, -1], 1 - (step.float() + 1) / T)
    assert torch.equal(data["next", "reward"].squeeze(-1), torch.from_numpy(rewards[:, 0]))

    out = path.with_suffix(".pt")
    save_demonstrations(out, Demonstrations(data, meta))
    data2, meta2 = load_demonstrations(out)
    assert meta2 == meta and (data2 == data).all() and data2.batch_size == (n,)


# ---------------------------------------------------------------- dimension check
def test_check_dims_messages(teacher_dir):
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

    with pytest.raises(ValueError, match=r"'action' has 3 dims, env action has 6"):
        check_demonstration_dims(demos.data, observation_dim=12, action_dim=6, source="x.npz")

    with pytest.raises(TypeError, match="observation_dim"):
        check_demonstration_dims(demos)


def test_check_dims_from_env_specs(teacher_dir):
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
