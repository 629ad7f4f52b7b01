"""DivergenceCheck: non-finite losses and parameters stop a run, naming the quantity and the frame."""

from __future__ import annotations

import json

import pytest
import torch
from example_runner import read_scalar, run, saved
from torch import nn

from torchrl_sail import DivergenceCheck, DivergenceError


def nets():
    torch.manual_seed(0)
    return {"critic": nn.Sequential(nn.Linear(3, 4), nn.ReLU(), nn.Linear(4, 1)), "norm": nn.BatchNorm1d(3)}


def test_finite_passes_and_bookkeeping_is_not_checked():
    check = DivergenceCheck(nets())
    # Python numbers are bookkeeping (the threshold is -inf until W_k fills): not checked
    assert check({"sail/loss_qvalue": torch.tensor(0.3), "teacher/threshold": float("-inf")}, frame=1000) is None
    assert len(check.named_tensors()) == 4 + 2 + 2  # 2 linears' weights and biases, BN weight/bias, running mean/var


def test_large_finite_values_pass_and_later_state_is_checked():
    modules = nets()
    check = DivergenceCheck(modules)
    with torch.no_grad():
        modules["critic"][0].weight.fill_(1e20)  # finite (a norm would overflow float32 here)
    check({}, frame=1)
    DivergenceCheck({})({}, frame=1)  # nothing to check
    DivergenceCheck({})({"loss": torch.tensor(1.0, dtype=torch.float64)}, frame=1)
    # state registered after the check was built (RND's statistics appear at the env's first step)
    modules["norm"].register_buffer("late", torch.tensor([float("inf")]))
    with pytest.raises(DivergenceError) as err:
        check({}, frame=2)
    assert err.value.quantities == ["norm.late"]


def test_nan_loss_is_named_with_the_frame():
    check = DivergenceCheck(nets())
    with pytest.raises(DivergenceError, match=r"at frame 12000: d/loss_discriminator=nan") as err:
        check({"sail/loss_qvalue": torch.tensor(0.3), "d/loss_discriminator": torch.tensor(float("nan"))}, frame=12000)
    assert err.value.quantities == ["d/loss_discriminator"] and err.value.frame == 12000


@pytest.mark.parametrize(
    "name, value",
    [("critic.2.weight", float("inf")), ("critic.0.bias", float("nan")), ("norm.running_var", float("nan"))],
)
def test_non_finite_parameter_or_buffer_is_named(name, value):
    modules = nets()
    check = DivergenceCheck(modules)
    with torch.no_grad():
        dict(
            [
                *modules[name.split(".")[0]].named_parameters(prefix=name.split(".")[0]),
                *modules[name.split(".")[0]].named_buffers(prefix=name.split(".")[0]),
            ]
        )[name].view(-1)[0] = value
    with pytest.raises(DivergenceError, match=rf"at frame 7: {name}") as err:
        check({"sail/loss_qvalue": torch.tensor(0.3)}, frame=7)
    assert err.value.quantities == [name]


def test_error_says_what_to_do_with_the_checkpoint_and_counts_the_rest():
    modules = {f"net{i}": nn.Linear(2, 2) for i in range(6)}
    check = DivergenceCheck(modules, unit="BC step")
    for module in modules.values():
        with torch.no_grad():
            module.weight.fill_(float("nan"))
            module.bias.fill_(float("nan"))
    with pytest.raises(DivergenceError) as err:
        check({}, frame=30, checkpoint="run/checkpoint, frame 20")
    message = str(err.value)
    assert message.startswith("non-finite value at BC step 30: net0.weight, net0.bias")
    assert "and 4 more" in message and "last good checkpoint (run/checkpoint, frame 20)" in message
    assert "resume=true" in message and len(err.value.quantities) == 12


def test_rejects_a_non_module():
    with pytest.raises(TypeError, match=r"modules\['critic'\] is a Tensor"):
        DivergenceCheck({"critic": torch.zeros(2)})


TINY = [
    "env=Hopper-v4",
    "collector.init_random_frames=1000",
    "collector.frames_per_batch=500",
    "optim.updates_per_train=50",
    "optim.discriminator.steps=2",
    "eval.every_frames=0",
    "logger.log_every_frames=500",
    "logger.backends=[csv]",
    "checkpoint.every_frames=1000",
]


@pytest.mark.slow
def test_diverging_run_stops_keeps_its_checkpoint_and_resumes_with_other_settings(tmp_path):
    """A NaN injected through an absurd learning rate (1e12) at the continuation of a healthy run."""
    run_dir = tmp_path / "run"
    run(run_dir, "collector.total_frames=1500", *TINY)  # checkpoint at 1000 and at the end (1500)
    manifest = (run_dir / "checkpoint" / "manifest.json").read_bytes()

    proc = run(run_dir, "collector.total_frames=2500", "resume=true", "optim.lr=1e12", *TINY, check=False)
    assert proc.returncode != 0
    assert "DivergenceError: non-finite value at frame 2000: sail/loss_qvalue=nan" in proc.stderr
    assert f"last good checkpoint ({run_dir / 'checkpoint'}, frame 1500)" in proc.stderr
    # nothing non-finite was logged or saved: the checkpoint is the healthy run's, byte for byte
    assert (run_dir / "checkpoint" / "manifest.json").read_bytes() == manifest
    assert [frame for frame, _ in read_scalar(run_dir, "sail/loss_qvalue")][-1] == 1500
    assert not (run_dir / "summary.json").exists()  # unfinished: no summary of its first 1500 frames
    state = saved(run_dir, "run", "loss")
    assert state["run"]["frames"] == 1500
    assert all(torch.isfinite(v).all() for v in state["loss"].values() if torch.is_tensor(v) and v.is_floating_point())

    # continued with the default learning rate, the run goes on from the checkpoint and finishes
    run(run_dir, "collector.total_frames=2500", "resume=true", *TINY)
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["frames"] == 2500 and summary["gradient_steps"] == 100
    assert all(value == value and abs(value) < 1e6 for _, value in read_scalar(run_dir, "sail/loss_qvalue"))
