"""``collector.backend=ray`` end to end: 2 Ray actors collect, the learner trains and pushes its
weights to the actors after every batch (TorchRL's ``RayWeightSyncScheme``)."""

from __future__ import annotations

import json
import shutil
import subprocess

import pytest
import torch
from torch import nn

ray = pytest.importorskip("ray", reason="the ray backend tests need Ray: pip install -e '.[ray]'")

from example_runner import run, saved  # noqa: E402
from tensordict import TensorDict  # noqa: E402
from tensordict.nn import TensorDictModule, TensorDictSequential  # noqa: E402
from torchrl.modules import MLP, TanhModule  # noqa: E402

from torchrl_sail import TRANSITION_KEYS, make_sail_env, save_demonstrations  # noqa: E402

ENV = "InvertedPendulum-v4"
CELLS = [64, 64]
# Warm-up 500 random frames, then batches of 250 (125 per actor). One training block (20 TD3
# steps, 10 actor steps) at 1000 frames, none after it: the rows collected from 1000 to 1750
# come from the weights pushed after that block, which are also the checkpoint's final actor.
# env.exploration_noise=0 makes the collected actions the actor's deterministic actions.
BUDGET = [
    f"env={ENV}",
    "env.exploration_noise=0",
    "collector.backend=ray",
    "collector.num_workers=2",
    "collector.total_frames=1750",
    "collector.init_random_frames=500",
    "collector.frames_per_batch=250",
    "optim.updates_per_train=20",
    "optim.discriminator.steps=2",
    f"network.actor_cells=[{CELLS[0]},{CELLS[1]}]",
    f"network.critic_cells=[{CELLS[0]},{CELLS[1]}]",
    f"network.discriminator_cells=[{CELLS[0]},{CELLS[1]}]",
    "eval.every_frames=0",
    "logger.backends=[csv]",
    "checkpoint.every_frames=0",
]


def loopback_only() -> tuple[str, ...]:
    """A command prefix that runs the example in a new network namespace with loopback only.

    Ray binds its servers to every interface and connects through the machine's routable
    address even when told 127.0.0.1; in a namespace of its own that address does not exist.
    """
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        pytest.skip("needs unshare and ip (util-linux, iproute2) to keep Ray on a loopback-only network")
    if subprocess.run(["unshare", "-n", "true"], capture_output=True).returncode != 0:
        pytest.skip("cannot create a network namespace here (unshare -n needs root or user namespaces)")
    return ("unshare", "-n", "sh", "-c", 'ip link set lo up && exec "$@"', "sh")


def weak_teacher(path) -> None:
    """The longest of 5 seeded random-policy episodes, in the project's format."""
    env = make_sail_env(ENV, delayed_reward=False)
    env.set_seed(123)
    torch.manual_seed(123)
    best = max((env.rollout(1000, break_when_any_done=True) for _ in range(5)), key=lambda r: r.numel())
    save_demonstrations(path, best.select(*TRANSITION_KEYS, "step_count"), {"env_id": ENV})


def final_actor(loss_state: dict, env) -> TensorDictSequential:
    """The example's deterministic TD3 actor (MLP -> TanhModule) with the checkpoint's weights."""
    mlp = MLP(
        in_features=env.observation_spec["observation"].shape[-1],
        out_features=env.action_spec.shape[-1],
        num_cells=CELLS,
        activation_class=nn.ReLU,
    )
    prefix = "actor_network_params.module.0.module."
    mlp.load_state_dict({key[len(prefix) :]: value for key, value in loss_state.items() if key.startswith(prefix)})
    return TensorDictSequential(
        TensorDictModule(mlp, in_keys=["observation"], out_keys=["param"]),
        TanhModule(in_keys=["param"], out_keys=["action"], spec=env.action_spec),
    )


def test_ray_collector_trains_and_pushes_weights(tmp_path):
    prefix = loopback_only()
    weak_teacher(tmp_path / "teacher")
    run_dir = tmp_path / "run"
    # no ray_init_config: the collector starts (and stops) a local Ray instance of 2 CPUs
    options = "{ray_init_config: {num_cpus: 2, include_dashboard: false}, remote_configs: {num_cpus: 1, num_gpus: 0}}"
    run(run_dir, *BUDGET, f"teacher.path={tmp_path / 'teacher'}", f"collector.backend_options={options}", prefix=prefix)

    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["frames"] == 1750 and summary["gradient_steps"] == 20, summary
    state = saved(run_dir, "loss", "replay")
    data = state["replay"]["data"]
    assert state["replay"]["size"] == 1750
    # Each [2 actors, 125] batch is stored actor by actor, so every row range below spans both actors.
    env = make_sail_env(ENV)
    with torch.no_grad():
        learner = final_actor(state["loss"], env)(TensorDict(observation=data["observation"], batch_size=[1750]))
    after, before = slice(1000, 1750), slice(500, 1000)
    # The weights reached both actors: after the push, they acted as the learner's trained actor ...
    torch.testing.assert_close(data["action"][after], learner["action"][after])
    # ... which is not the actor they started with (so the check above is not vacuous).
    assert (data["action"][before] - learner["action"][before]).abs().max() > 1e-3
