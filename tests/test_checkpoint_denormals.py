"""``benchmarks/checkpoint_denormals.py``: denormal floats in a run's networks and Adam moments."""

from __future__ import annotations

import shutil

import pytest
import torch
from benchmark_scripts import load_benchmark
from example_runner import run
from omegaconf import OmegaConf
from test_example import HOPPER, TINY

checkpoint_denormals = load_benchmark("checkpoint_denormals")


def test_denormal_count_and_table_against_hand_counted_values():
    # 1e-39 and -1e-40 are denormal; 0, 1.2e-38 (above the smallest normal, 1.18e-38) and 1e-30 are not
    moments = torch.tensor([0.0, 1e-39, -1e-40, 1.2e-38, 1e-30])
    assert checkpoint_denormals.denormal_count(moments) == 2
    if torch.set_flush_denormal(True):  # counted from the bits: also where this process flushes them
        try:
            assert checkpoint_denormals.denormal_count(moments) == 2
        finally:
            torch.set_flush_denormal(False)
    lines = checkpoint_denormals.table(
        {"optim_actor": {"w.exp_avg": moments, "w.exp_avg_sq": torch.ones(3)}, "loss": {"w": torch.ones(2, 2)}}
    ).splitlines()
    assert lines[2:] == [
        "| optim_actor | w.exp_avg | (5,) | 2 | 40.0% |",
        "| optim_actor | **all** | | **2** | 25.0% |",  # 2 of 8 values
        "| loss | **all** | | **0** | 0.0% |",
    ]


def test_a_sail_checkpoint_gives_each_parameter_and_its_adam_moments(tmp_path, teacher_dir, capsys):
    run_dir = tmp_path / "sail"
    run(
        run_dir,
        "algo=sail",
        f"teacher.path={teacher_dir / HOPPER}",
        "env=Hopper-v4",
        "collector.total_frames=2000",
        "logger.backends=[csv]",
        "checkpoint.every_frames=1000",
        *TINY,
    )
    tensors = checkpoint_denormals.main([str(run_dir)])
    assert "| optim_critic | **all** |" in capsys.readouterr().out
    actor = {name: t for name, t in tensors["loss"].items() if name.startswith("actor_network_params")}
    assert actor and all(t.dtype == torch.float32 for t in actor.values())
    # the optimizers came back with the run's state (a fresh Adam has none): both moments of every parameter
    for group, params in (("optim_actor", "actor_network_params"), ("optim_critic", "qvalue_network_params")):
        names = {name for name in tensors["loss"] if name.startswith(params)}
        assert set(tensors[group]) == {f"{name}.{key}" for name in names for key in ("exp_avg", "exp_avg_sq")}
        assert any(bool(t.abs().sum() > 0) for t in tensors[group].values())
    other = tmp_path / "bc"
    shutil.copytree(run_dir, other)
    config = OmegaConf.load(other / "config.yaml")
    config.algo.name, config.algo.learner = "bc", "bc"
    OmegaConf.save(config, other / "config.yaml")
    with pytest.raises(ValueError, match="algo=bc is not a TD3 method"):
        checkpoint_denormals.main([str(other)])
