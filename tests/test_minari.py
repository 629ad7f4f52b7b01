"""Tests for torchrl_sail.data.minari (Minari datasets: export, load, checks, the example)."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from tensordict import TensorDict

from torchrl_sail import (
    Demonstrations,
    export_minari_dataset,
    load_demonstrations,
    load_minari_demonstrations,
)

minari = pytest.importorskip("minari")  # in the `test` extra: never skipped on CI
from minari.data_collector import EpisodeBuffer  # noqa: E402
from minari.dataset.minari_storage import MinariStorage  # noqa: E402

SHIPPED = Path(__file__).resolve().parents[1] / "examples" / "teachers"
PAPER_HOPPER = "expert_data_no_img_Hopper_scores_1500_episodes_1.npz"
ID = "sail/toy/demo-v0"


@pytest.fixture
def root(tmp_path, monkeypatch) -> Path:
    """A fresh MINARI_DATASETS_PATH."""
    root = tmp_path / "minari"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    return root


def _episodes(lengths=(3, 4), terminated=(True, False), obs_dim=3, act_dim=2) -> TensorDict:
    """Whole episodes, each ending terminated or truncated; distinct values everywhere."""
    parts = []
    for i, (T, term) in enumerate(zip(lengths, terminated, strict=True)):
        obs = torch.randn(T + 1, obs_dim)
        done = torch.arange(T)[:, None] == T - 1
        parts.append(
            TensorDict(
                {
                    "observation": obs[:-1],
                    "action": torch.rand(T, act_dim) * 2 - 1,
                    ("next", "observation"): obs[1:],
                    ("next", "reward"): torch.randn(T, 1) + 10 * i,
                    ("next", "done"): done,
                    ("next", "terminated"): done & term,
                    ("next", "truncated"): done & (not term),
                },
                batch_size=[T],
            )
        )
    return torch.cat(parts)


def _assert_same(data, expected, keys=None):
    keys = list(expected.keys(True, True)) if keys is None else keys
    for key in keys:
        assert data[key].dtype == expected[key].dtype, key
        assert torch.equal(data[key], expected[key]), key


def _write_raw(root: Path, dataset_id: str, episodes, obs_space, act_space) -> Path:
    """A dataset written by Minari's storage directly (to make bad ones)."""
    folder = root / dataset_id
    folder.mkdir(parents=True)
    storage = MinariStorage.new(folder / "data", observation_space=obs_space, action_space=act_space)
    storage.update_metadata({"dataset_id": dataset_id, "minari_version": minari.__version__})
    storage.update_episodes([EpisodeBuffer(**episode) for episode in episodes])
    return folder


def _raw_episode(T=3, obs_dim=3, act_dim=2, end=True, obs=None):
    return dict(
        observations=np.random.randn(T + 1, obs_dim).astype(np.float32) if obs is None else obs,
        actions=np.zeros((T, act_dim), np.float32),
        rewards=np.ones(T, np.float32),
        terminations=np.arange(T) == T - 1 if end else np.zeros(T, bool),
        truncations=np.zeros(T, bool),
    )


BOX3, BOX2 = gym.spaces.Box(-np.inf, np.inf, (3,), np.float32), gym.spaces.Box(-1, 1, (2,), np.float32)


def test_round_trip_by_id_and_path(root):
    td = _episodes()
    path = export_minari_dataset(td, ID, author="me", algorithm_name="hand-made")
    assert path == root / ID and (path / "data" / "main_data.hdf5").is_file()
    assert not [p for p in path.parent.iterdir() if p.name.startswith(".")]  # no staging left
    assert minari.load_dataset(ID).total_episodes == 2  # Minari reads it too
    expected_returns = [float(td["next", "reward"][s:e].double().sum()) for s, e in ((0, 3), (3, 7))]
    for source in (f"minari:{ID}", path, path / "data", str(path)):
        data, meta = load_demonstrations(source)
        _assert_same(data, td)
        assert data["step_count"].squeeze(-1).tolist() == [0, 1, 2, 0, 1, 2, 3]
        assert data["next", "terminated"].squeeze(-1).tolist() == [False, False, True] + [False] * 4
        assert data["next", "truncated"].squeeze(-1).tolist() == [False] * 6 + [True]
        assert meta["episode_returns"] == expected_returns and meta["episode_lengths"] == [3, 4]
        assert meta["source"] == str(path) and meta["dataset_id"] == ID and meta["format"] == "minari"
        assert meta["author"] == ["me"] and meta["algorithm_name"] == "hand-made"
        assert "env_id" not in meta and meta["time_feature"] is False
    data, _ = load_minari_demonstrations(ID)  # a bare id
    _assert_same(data, td)


def test_missing_dataset_names_id_and_path(root):
    with pytest.raises(FileNotFoundError) as err:
        load_demonstrations("minari:sail/nothing/here-v0")
    message = str(err.value)
    assert "'sail/nothing/here-v0'" in message and str(root / "sail/nothing/here-v0" / "data") in message
    assert "minari download sail/nothing/here-v0" in message
    with pytest.raises(FileNotFoundError, match="not a Minari dataset folder"):
        load_minari_demonstrations(root / "absent")


def test_overwrite_refused_then_atomic(root, monkeypatch):
    td = _episodes()
    export_minari_dataset(td, ID)
    with pytest.raises(FileExistsError, match="overwrite=True"):
        export_minari_dataset(_episodes(), ID)
    _assert_same(load_minari_demonstrations(ID).data, td)

    def fail(self, episodes):
        raise OSError("disk full")

    monkeypatch.setattr(type(MinariStorage.read(root / ID / "data")), "update_episodes", fail)
    with pytest.raises(OSError, match="disk full"):
        export_minari_dataset(_episodes(), ID, overwrite=True)
    _assert_same(load_minari_demonstrations(ID).data, td)  # the old dataset is intact
    assert sorted(p.name for p in (root / "sail" / "toy").iterdir()) == ["demo-v0", "namespace_metadata.json"]
    monkeypatch.undo()
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    other = _episodes((2,), (False,))
    export_minari_dataset(other, ID, overwrite=True)
    _assert_same(load_minari_demonstrations(ID).data, other)


def test_export_checks(root):
    td = _episodes()
    with pytest.raises(ValueError, match=r"is not \(namespace/\)name-v<version>"):
        export_minari_dataset(td, "sail/no-version")
    broken = td.clone()
    broken["next", "observation"][1] += 1  # not the observation of row 2
    with pytest.raises(ValueError, match=r"episode 0: \('next', 'observation'\) of row 1"):
        export_minari_dataset(broken, ID)
    with pytest.raises(ValueError, match="the last row is not done"):
        export_minari_dataset(td[:5], ID)
    with pytest.raises(ValueError, match="starts at step_count=5"):
        export_minari_dataset(td.clone().set("step_count", torch.arange(5, 12)[:, None]), ID)
    with pytest.raises(ValueError, match="episode 1 has recorded return 1.000000 .* delayed"):
        export_minari_dataset(Demonstrations(td, {"episode_returns": [float(td["next", "reward"][:3].sum()), 1.0]}), ID)
    with pytest.raises(ValueError, match="'action' has 2 dims but env Hopper-v4"):
        export_minari_dataset(td, ID, env="Hopper-v4")
    with pytest.raises(ValueError, match="cannot make the env 'Hoper-v4'"):
        export_minari_dataset(td, ID, env="Hoper-v4")
    assert not root.exists() or not any(root.rglob("main_data.hdf5"))


def test_dict_observation_space_is_rejected(root):
    space = gym.spaces.Dict({"position": BOX3})
    episode = _raw_episode(obs={"position": np.zeros((4, 3), np.float32)})
    _write_raw(root, "bad/dict-v0", [episode], space, BOX2)
    with pytest.raises(ValueError, match=r"the observation space is Dict\('position'.*only flat Box"):
        load_demonstrations("minari:bad/dict-v0")


@pytest.mark.parametrize(
    "case, message",
    [
        ("dims", r"episode 0: observations \(4, 3\), .* expected \(T \+ 1, 4\)"),
        ("no_end", "episode 1 does not end with terminated or truncated"),
        ("early_end", "episode 0 is done at step 0, before its last step 2"),
        ("too_long", "episode 0 has 3 steps, more than max_episode_steps=2"),
        ("actions", r"actions leave the action space Box\(-1.0, 1.0, \(2,\), float32\) by 1"),
        ("rewards_sum", "episode 0 has rewards_sum 7.000000 but its rewards sum to 3.000000"),
    ],
)
def test_bad_datasets_are_rejected(root, case, message):
    episodes, obs_space = [_raw_episode(), _raw_episode(end=case != "no_end")], BOX3
    if case == "dims":
        obs_space = gym.spaces.Box(-np.inf, np.inf, (4,), np.float32)
    if case == "early_end":
        episodes[0]["truncations"] = np.array([True, False, True])
    if case == "actions":
        episodes[1]["actions"][1, 0] = 2.0
    folder = _write_raw(root, f"bad/{case.replace('_', '')}-v0", episodes, obs_space, BOX2)
    if case == "rewards_sum":
        MinariStorage.read(folder / "data").update_episode_metadata([{"rewards_sum": 7.0}, {"rewards_sum": 3.0}])
    with pytest.raises(ValueError, match=message):
        load_minari_demonstrations(folder, max_episode_steps=2 if case == "too_long" else 1000)


def test_time_feature(root):
    # a dataset recorded on the plain env: no time column
    td = _episodes(obs_dim=3)
    export_minari_dataset(td, "plain/env-v0")
    data, meta = load_minari_demonstrations("plain/env-v0")
    assert meta["time_feature"] is False and data["observation"].shape[-1] == 3
    data, meta = load_minari_demonstrations("plain/env-v0", time_feature=True, max_episode_steps=10)
    assert meta["time_feature"] is True and meta["time_feature_appended"] is True
    t = data["step_count"].double()
    assert torch.equal(data["observation"][:, :3], td["observation"])
    assert torch.equal(data["observation"][:, 3:], (1 - t / 10).float())
    assert torch.equal(data["next", "observation"][:, 3:], (1 - (t + 1) / 10).float())
    # recorded with the time feature of T = 10: detected with T = 10, an error with T = 1000
    export_minari_dataset(data, "with/feature-v0")
    again, meta = load_minari_demonstrations("with/feature-v0", max_episode_steps=10)
    assert meta["time_feature"] is True and meta["time_feature_appended"] is False
    _assert_same(again, data)
    for time_feature in (None, True):
        with pytest.raises(ValueError, match="time feature 1 - t/T with T=10, not max_episode_steps=1000"):
            load_minari_demonstrations("with/feature-v0", time_feature=time_feature)
    assert load_minari_demonstrations("with/feature-v0", time_feature=False)[1]["time_feature"] is False


def test_shipped_teacher_round_trip(root):
    demos = load_demonstrations(SHIPPED / "Hopper-v4")
    path = export_minari_dataset(demos, "sail/Hopper-v4/teacher-v0")  # env from the metadata's env_id
    data, meta = load_demonstrations("minari:sail/Hopper-v4/teacher-v0")
    _assert_same(data, demos.data)  # step_count included
    assert meta["episode_returns"] == demos.metadata["episode_returns"] and meta["episode_lengths"] == [165]
    assert meta["env_id"] == "Hopper-v4" and meta["time_feature"] is True
    assert meta["exported_from"] == demos.metadata["source"] and meta["made_by"] == demos.metadata["made_by"]
    dataset = minari.load_dataset("sail/Hopper-v4/teacher-v0")
    assert dataset.spec.env_spec.id == "Hopper-v4" and path == root / "sail/Hopper-v4/teacher-v0"
    assert dataset.action_space == gym.spaces.Box(-1, 1, (3,), np.float32)  # the env's


def test_paper_teacher_round_trip(root, teacher_dir):
    demos = load_demonstrations(teacher_dir / PAPER_HOPPER)
    export_minari_dataset(demos, "sail/Hopper-v4/paper-v0", env="Hopper-v4")
    data, meta = load_demonstrations("minari:sail/Hopper-v4/paper-v0")
    _assert_same(data, demos.data)  # the approximated final next state included
    assert meta["episode_returns"] == demos.metadata["episode_returns"]  # the recorded float64 returns
    assert meta["episode_lengths"] == [425] and meta["nominal_score"] == 1500.0


def test_missing_minari_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "minari", None)
    with pytest.raises(ImportError, match=r"pip install -e '\.\[minari\]'"):
        load_demonstrations("minari:sail/Hopper-v4/teacher-v0")


@pytest.mark.slow
def test_example_trains_on_a_minari_teacher(root, tmp_path):
    # A dataset in the D4RL layout (plain Hopper-v4 observations, no time column): the example
    # appends the column its env has (teacher.path=minari:<id>) and runs.
    from example_runner import run

    demos = load_demonstrations(SHIPPED / "Hopper-v4")
    plain = demos.data.clone()
    for key in ("observation", ("next", "observation")):
        plain[key] = plain[key][:, :-1].contiguous()
    export_minari_dataset(plain, "d4rl-like/hopper/teacher-v0", env="Hopper-v4")
    run_dir = tmp_path / "run"
    run(
        run_dir,
        "env=Hopper-v4",
        "teacher.path=minari:d4rl-like/hopper/teacher-v0",
        "collector.total_frames=200",
        "collector.init_random_frames=100",
        "collector.frames_per_batch=100",
        "optim.train_every_frames=100",
        "optim.updates_per_train=2",
        "optim.batch_size=32",
        "optim.discriminator.every_frames=100",
        "optim.discriminator.steps=1",
        "optim.discriminator.batch_size=16",
        "eval.every_frames=0",
        "checkpoint.every_frames=0",
        "logger.backends=[csv]",
        env={"MINARI_DATASETS_PATH": str(root)},
    )
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["teacher_source"] == "minari:d4rl-like/hopper/teacher-v0" and summary["frames"] == 200
    assert summary["teacher_return"] == pytest.approx(demos.metadata["episode_returns"][0])
    assert summary["teacher_threshold"] == 46.0  # floor(0.1 * 463.6): the demonstration is in the buffer


def test_non_finite_values_are_rejected(root):
    episodes = [_raw_episode(), _raw_episode()]
    episodes[1]["observations"][2, 1] = np.nan
    folder = _write_raw(root, "bad/nan-v0", episodes, BOX3, BOX2)
    with pytest.raises(
        ValueError,
        match=r"nan-v0: episode 1: 'observations' has a non-finite value \(nan\) at "
        r"step 2, column 1",
    ):
        load_demonstrations(folder)
    episodes = [_raw_episode(), _raw_episode()]
    episodes[0]["rewards"][1] = np.inf
    folder = _write_raw(root, "bad/inf-v0", episodes, BOX3, BOX2)
    with pytest.raises(ValueError, match=r"inf-v0: episode 0: 'rewards' has a non-finite value \(inf\) at step 1"):
        load_demonstrations("minari:bad/inf-v0")
    folder = _write_raw(root, "bad/nansum-v0", [_raw_episode(), _raw_episode()], BOX3, BOX2)
    MinariStorage.read(folder / "data").update_episode_metadata([{"rewards_sum": 3.0}, {"rewards_sum": float("nan")}])
    with pytest.raises(ValueError, match=r"nansum-v0: 'rewards_sum' has a non-finite value \(nan\) at episode 1"):
        load_demonstrations(folder)
    td = _episodes()
    td["action"][4, 1] = float("nan")
    with pytest.raises(
        ValueError,
        match=r"demonstrations to export as 'sail/toy/demo-v0': 'action' has a "
        r"non-finite value \(nan\) at row 4, column 1",
    ):
        export_minari_dataset(td, ID)
    assert not (root / ID).exists()


def test_export_uses_minari_public_api_and_root(tmp_path, monkeypatch):
    # root= without MINARI_DATASETS_PATH: the variable Minari's functions read is set only
    # during the export, then restored
    monkeypatch.delenv("MINARI_DATASETS_PATH", raising=False)
    root = tmp_path / "elsewhere"
    td = _episodes()
    path = export_minari_dataset(td, "sail/nested/toy/demo-v1", root=root, author=["a", "b"])
    assert "MINARI_DATASETS_PATH" not in os.environ
    assert path == root / "sail/nested/toy/demo-v1"
    assert sorted(p.name for p in root.iterdir()) == ["sail"]  # no scratch folder left
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    assert minari.list_local_datasets().keys() == {"sail/nested/toy/demo-v1"}
    from minari.namespace import list_local_namespaces

    assert list_local_namespaces() == ["sail", "sail/nested", "sail/nested/toy"]
    data, meta = load_minari_demonstrations("sail/nested/toy/demo-v1")
    _assert_same(data, td)
    assert meta["author"] == ["a", "b"] and meta["data_format"] == "hdf5"
    assert meta["minari_version"] == minari.__version__ and meta["dataset_id"] == "sail/nested/toy/demo-v1"


def test_failed_export_leaves_nothing(root, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # data_format="arrow" needs it
    with pytest.raises(ImportError, match="pyarrow"):
        export_minari_dataset(_episodes(), ID, data_format="arrow")
    assert not root.exists() or not [p for p in root.rglob("*") if p.is_file() or p.name.startswith(".")]
    assert os.environ["MINARI_DATASETS_PATH"] == str(root)
