"""``torchrl_sail._compat``: every private TorchRL API the package and its examples use still exists and
behaves as relied on (checked against torchrl 0.14.1: an upgrade that changes one fails here, naming it)."""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
import inspect
from datetime import timedelta
from pathlib import Path

import pytest
import tensordict
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.data import Bounded
from torchrl.modules import MLP, TanhModule, ValueOperator
from torchrl.objectives import SoftUpdate

from torchrl_sail import SAILLoss, _compat, make_sail_env


def test_checked_against_this_torchrl_minor_version():
    installed = importlib.metadata.version("torchrl")
    assert installed.split(".")[:2] == _compat.TORCHRL_VERSION.split(".")[:2], (
        f"torchrl {installed} is installed, torchrl_sail._compat was checked against {_compat.TORCHRL_VERSION}: "
        f"check every entry of torchrl_sail/_compat.py, then update TORCHRL_VERSION"
    )


@pytest.mark.parametrize(
    "owner, name", [(owner, name) for owner, names in _compat.SUBCLASS_HOOKS.items() for name in names]
)
def test_subclass_hooks_exist(owner, name):
    module, _, cls = owner.rpartition(".")
    assert callable(getattr(getattr(importlib.import_module(module), cls), name))


def td3_loss():
    spec = Bounded(-2.0, 2.0, (2,))
    actor = TensorDictSequential(
        TensorDictModule(MLP(in_features=3, out_features=2, num_cells=[8]), ["observation"], ["param"]),
        TanhModule(["param"], ["action"], spec=spec),
    )
    critic = ValueOperator(MLP(in_features=5, out_features=1, num_cells=[8]), in_keys=["action", "observation"])
    loss = SAILLoss(actor, critic, action_spec=spec)
    loss.make_value_estimator(gamma=0.99)
    return loss, spec


def test_soft_update_pairs_are_softupdates_own():
    loss, _ = td3_loss()
    updater = SoftUpdate(loss, tau=0.1)
    sources, targets = _compat.soft_update_pairs(updater)
    assert len(sources) == len(targets) >= 8  # the actor's and the critics' weights and biases (and buffers)
    assert all(source.shape == target.shape for source, target in zip(sources, targets, strict=True))
    with torch.no_grad():
        for source in sources:
            source.add_(1.0)  # move the sources away from the targets
    expected = [target + 0.1 * (source - target) for source, target in zip(sources, targets, strict=True)]
    updater.step()  # TorchRL's own Polyak step moves exactly these tensors
    for target, value in zip(targets, expected, strict=True):
        torch.testing.assert_close(target, value)


def test_reduce_loss_is_the_losss_reduction():
    loss, _ = td3_loss()
    batch = TensorDict({}, [4])
    assert _compat.reduce_loss(loss, torch.tensor([1.0, 2.0, 3.0, 6.0]), batch).item() == 3.0  # "mean"


def test_mlp_params_paths_and_tanh_bounds():
    loss, spec = td3_loss()
    actor_mlp = _compat.mlp_params(loss.actor_network_params, _compat.ACTOR_MLP_PATH)
    assert actor_mlp["0", "weight"].shape == (8, 3) and actor_mlp["2", "bias"].shape == (2,)
    critic_mlp = _compat.mlp_params(loss.qvalue_network_params, _compat.CRITIC_MLP_PATH)
    assert critic_mlp["0", "weight"].shape == (2, 8, 5)  # the twin critics, stacked
    low, high = _compat.tanh_bounds(loss.actor_network.module[1])
    assert torch.equal(low, spec.space.low) and torch.equal(high, spec.space.high)
    # the loss's own copy moves with loss.to(...); the module's buffers stay behind
    loss.to(torch.float64)
    tanh_params = loss.actor_network_params[_compat.ACTOR_TANH_PATH]
    low, high = _compat.tanh_bounds(loss.actor_network.module[1], tanh_params)
    assert low.dtype == high.dtype == torch.float64 and torch.equal(high, spec.space.high.double())
    assert _compat.tanh_bounds(loss.actor_network.module[1])[0].dtype == torch.float32


def test_env_privates():
    env = make_sail_env("Hopper-v4", max_episode_steps=10)
    assert _compat.filtered_reset_keys(env) == ["_reset"]
    assert _compat.render_fps(env) == 125  # 1 / dt
    data = TensorDict({"_reset": torch.tensor([[True], [False]])}, [2])
    assert _compat.reset_mask("_reset", data).tolist() == [True, False]
    assert _compat.reset_mask("_reset", TensorDict({}, [3])).tolist() == [True] * 3  # absent: every entry


def test_ray_weight_sync_timeout_is_the_one_the_scheme_reads(monkeypatch):
    from torchrl.weight_update import _ray

    assert _ray._DIST_TIMEOUT == timedelta(seconds=60)  # TorchRL's fixed value, what the setting replaces
    monkeypatch.setattr(_ray, "_DIST_TIMEOUT", _ray._DIST_TIMEOUT)  # restored after the test
    _compat.set_ray_weight_sync_timeout(300)
    assert _ray._DIST_TIMEOUT == timedelta(seconds=300)
    # the sender's TCPStore and gloo group read the module constant when they connect
    sender = inspect.getsource(_ray.RayWeightSyncScheme._setup_distributed_connection_sender)
    assert sender.count("_DIST_TIMEOUT") == 2


def test_multi_step():
    steps = TensorDict(
        {
            "next": {
                "reward": torch.ones(1, 4, 1),
                "done": torch.zeros(1, 4, 1, dtype=torch.bool),
                "observation": torch.arange(4.0).view(1, 4, 1),
            }
        },
        [1, 4],
    )
    out = _compat.multi_step(
        steps, done_key="done", done_keys=[], reward_keys=["reward"], mask_key=None, n_steps=2, gamma=0.5
    )
    assert out["next", "reward"].view(-1).tolist() == [1.5, 1.5, 1.5, 1.0]  # cut at the window's end
    assert out["next", "observation"].view(-1).tolist() == [1.0, 2.0, 3.0, 3.0]


def test_dropout_layer():
    assert isinstance(nn.Dropout(0.1), _compat.DropoutLayer) and not isinstance(nn.ReLU(), _compat.DropoutLayer)


@pytest.mark.parametrize("clamp", [False, True])
def test_tanh_map_is_tanh_modules_map(clamp):
    spec = Bounded(torch.tensor([-2.0, 0.0]), torch.tensor([0.5, 3.0]), (2,))
    tanh = TanhModule(["param"], ["action"], spec=spec, clamp=clamp)
    param = 4 * torch.randn(16, 2)
    expected = tanh(TensorDict({"param": param}, [16]))["action"]
    assert torch.equal(_compat.tanh_map(tanh, param, *_compat.tanh_bounds(tanh)), expected)


def test_native_bf16_matmul_follows_the_cpu_flags():
    """oneDNN runs bf16 products on AVX-512 (bw, vl, dq) or AMX; an AVX2-only x86 CPU emulates them."""
    lines = Path("/proc/cpuinfo").read_text().splitlines() if Path("/proc/cpuinfo").exists() else []
    flags = next((set(line.split(":", 1)[1].split()) for line in lines if line.startswith("flags")), set())
    if "avx2" not in flags:
        pytest.skip("not an x86 CPU with /proc/cpuinfo flags")
    native = _compat.native_bf16_matmul("cpu")
    if {"avx512bw", "avx512vl", "avx512dq"} <= flags or "amx_bf16" in flags:
        assert native
    else:
        assert not native
    assert _compat.native_bf16_matmul(torch.device("meta"))  # no emulation to warn about


def test_storage_tensordict_holds_the_rows_storage_get_reads():
    from torchrl.data import LazyTensorStorage

    storage = LazyTensorStorage(6)
    storage.set(torch.arange(4), TensorDict({"x": torch.arange(4.0)}, [4]))
    data = _compat.storage_tensordict(storage)
    assert data.batch_size == (6,)  # every row of the capacity
    index = torch.tensor([3, 0, 2])
    assert torch.equal(data[index]["x"], storage[index]["x"])


@pytest.fixture
def counted_from_any(monkeypatch):
    """``TensorDictBase.from_any`` as tensordict has it, counting its calls by the type of their object;
    whatever it was is back after the test."""
    current = TensorDictBase.__dict__["from_any"].__func__
    original = current.__wrapped__ if _compat.is_from_any_shortcut(current) else current
    calls = []

    def counted(cls, obj, **kwargs):
        calls.append(type(obj))
        return original(cls, obj, **kwargs)

    monkeypatch.setattr(TensorDictBase, "from_any", classmethod(counted))
    return calls


@pytest.mark.skipif(
    tuple(int(part) for part in tensordict.__version__.split(".")[:2]) >= (0, 15),
    reason="tensordict 0.15 has the shortcut itself: fast_tensor_outputs patches nothing",
)
def test_fast_tensor_outputs_changes_only_the_time(counted_from_any):
    calls = counted_from_any
    assert _compat.fast_tensor_outputs() is True  # tensordict 0.14: patched
    patched = TensorDictBase.__dict__["from_any"].__func__
    assert _compat.fast_tensor_outputs() is True  # idempotent: patched once
    assert TensorDictBase.__dict__["from_any"].__func__ is patched and _compat.is_from_any_shortcut(patched)
    original = patched.__wrapped__
    tensor, parameter = torch.arange(3.0), nn.Parameter(torch.ones(2))
    # a plain tensor is returned as it is, without the original's call, which returns it as it is too
    assert TensorDict.from_any(tensor) is tensor and TensorDict.from_any(tensor, device="cpu") is tensor
    assert calls == []
    assert original(TensorDict, tensor) is tensor and calls == [torch.Tensor]
    with pytest.raises(TypeError):  # the original's keywords only
        TensorDict.from_any(tensor, bogus=1)
    # anything else goes the original's way
    calls.clear()
    assert TensorDict.from_any(parameter) is parameter
    nested = {"a": torch.zeros(2), "b": {"c": torch.ones(2, 3)}}
    assert isinstance(TensorDict.from_any(nested), TensorDict)
    assert torch.equal(TensorDict.from_any([1.0, 2.0]), torch.tensor([1.0, 2.0]))
    assert calls == [nn.Parameter, dict, dict, list]  # the nested dict goes through from_any too
    assert (TensorDict.from_any(nested) == original(TensorDict, nested)).all()
    # the path it is for: a TensorDictModule's output tensor goes into its tensordict without the call
    calls.clear()
    linear = nn.Linear(3, 2)
    out = TensorDictModule(linear, ["x"], ["y"])(TensorDict({"x": torch.ones(4, 3)}, batch_size=[4]))
    assert torch.equal(out["y"], linear(torch.ones(4, 3))) and calls == []


@pytest.mark.skipif(
    tuple(int(part) for part in tensordict.__version__.split(".")[:2]) >= (0, 15),
    reason="tensordict 0.15 has the shortcut itself: fast_tensor_outputs patches nothing",
)
def test_fast_tensor_outputs_wraps_another_wrapper_of_from_any(counted_from_any):
    # a profiler's or a mock's functools.wraps wrapper is not the shortcut: it gets wrapped in turn
    current = TensorDictBase.__dict__["from_any"].__func__

    @functools.wraps(current)
    def foreign(cls, obj, **kwargs):
        return current(cls, obj, **kwargs)

    TensorDictBase.from_any = classmethod(foreign)
    assert _compat.fast_tensor_outputs() is True
    patched = TensorDictBase.__dict__["from_any"].__func__
    assert _compat.is_from_any_shortcut(patched) and patched.__wrapped__ is foreign
    tensor = torch.arange(3.0)
    assert TensorDict.from_any(tensor) is tensor and counted_from_any == []
