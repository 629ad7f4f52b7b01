"""Runs the training scripts (``examples/sail_td3.py``, ``gail.py``, ``bc.py``) and ``evaluate.py`` in a
process of their own, as a user would (shared by the example tests). Run folders are read with
``torchrl_sail.harness.read_scalar`` (re-exported here).

A run is a fork of an interpreter that has imported torch and TorchRL already (``fork_server``),
which saves each run ~5 s of imports (on Linux; ``TORCHRL_SAIL_TESTS_FORK=0``, a command prefix,
or a ``MUJOCO_GL`` other than unset or ``egl`` runs ``python <script>`` instead)."""

from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import torch
from fork_server import STARTUP_VARIABLES, ForkServer, ServerGone

from torchrl_sail.harness import read_scalar  # noqa: F401  (the tests read logged scalars with it)

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "examples"
SCRIPT = EXAMPLES / "sail_td3.py"  # the off-policy methods; gail.py: on-policy; bc.py: behaviour cloning


def with_test_device(overrides: tuple[str, ...]) -> tuple[str, ...]:
    """``overrides`` plus ``device=<the suite's --device>`` (tests/conftest.py), unless they set one."""
    device = os.environ.get("TORCHRL_SAIL_TEST_DEVICE", "cpu")
    if device == "cpu" or any(o.lstrip("+").startswith("device=") for o in overrides):
        return overrides
    return (*overrides, f"device={device}")


def start(run_dir: Path, *overrides: str, script: str = "sail_td3.py") -> subprocess.Popen:
    """Starts ``<script> hydra.run.dir=<run_dir> <overrides>`` without waiting (to kill it)."""
    env = {**os.environ, "WANDB_SILENT": "true"}
    return subprocess.Popen(
        [sys.executable, str(EXAMPLES / script), f"hydra.run.dir={run_dir}", *with_test_device(overrides)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=REPO,
    )


def run(
    run_dir: Path,
    *overrides: str,
    script: str = "sail_td3.py",
    check: bool = True,
    multirun: bool = False,
    env: dict | None = None,
    prefix: tuple[str, ...] = (),
) -> subprocess.CompletedProcess:
    """``python examples/<script> hydra.run.dir=<run_dir> <overrides>``; raises on failure if ``check``.

    ``script`` is ``sail_td3.py`` (the default: the off-policy methods), ``gail.py`` (gail, pofd) or
    ``bc.py``. With ``multirun=True`` it runs ``<script> -m hydra.sweep.dir=<run_dir> <overrides>``
    instead. ``env`` adds environment variables; ``prefix`` is a command the script runs under
    (e.g. ``unshare``).
    """
    env = {**os.environ, "WANDB_SILENT": "true", "HYDRA_FULL_ERROR": "0", **(env or {})}
    where = ["-m", f"hydra.sweep.dir={run_dir}"] if multirun else [f"hydra.run.dir={run_dir}"]
    overrides = with_test_device(overrides)
    proc = run_python([str(EXAMPLES / script), *where, *overrides], env=env, timeout=900, prefix=prefix)
    if check and proc.returncode != 0:
        raise AssertionError(f"{script} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}")
    return proc


def evaluate(*overrides: str, env: dict | None = None, check: bool = True) -> subprocess.CompletedProcess:
    """``python examples/evaluate.py <overrides>`` (``MUJOCO_GL=egl`` unless ``env`` says otherwise)."""
    env = {**os.environ, "MUJOCO_GL": "egl", **(env or {})}
    proc = run_python([str(EXAMPLES / "evaluate.py"), *overrides], env=env, timeout=600)
    if check and proc.returncode != 0:
        raise AssertionError(f"evaluate.py failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}")
    return proc


_SERVERS: dict[str | None, ForkServer | None] = {}  # by MUJOCO_GL; None once a server failed to start


def run_python(argv: list[str], *, env: dict, timeout: float, prefix: tuple[str, ...] = ()):
    """``[*prefix] python <argv>`` in the repository root with ``env``: a ``subprocess.CompletedProcess``
    with the output as text (through a fork server where it can, see the module's docstring)."""
    gl = env.get("MUJOCO_GL")
    startup = any(env.get(name) != os.environ.get(name) for name in STARTUP_VARIABLES)  # fixed in the server
    plain = prefix or startup or gl not in (None, "egl") or os.environ.get("TORCHRL_SAIL_TESTS_FORK") == "0"
    if plain or not sys.platform.startswith("linux"):  # forking after imports is unsafe on macOS
        return subprocess.run(
            [*prefix, sys.executable, *argv], capture_output=True, text=True, env=env, timeout=timeout, cwd=REPO
        )
    if gl not in _SERVERS:
        server_env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"} | ({"MUJOCO_GL": gl} if gl else {})
        _SERVERS[gl] = ForkServer(server_env)
    if _SERVERS[gl] is not None:
        out_dir = Path(tempfile.mkdtemp(prefix="fork-run-"))
        try:
            return _SERVERS[gl].run(argv, env=env, cwd=REPO, timeout=timeout, out_dir=out_dir)
        except ServerGone:  # e.g. it could not import TorchRL with this MUJOCO_GL: run the script plainly
            _SERVERS[gl] = None
        finally:
            shutil.rmtree(out_dir, ignore_errors=True)
    return subprocess.run([sys.executable, *argv], capture_output=True, text=True, env=env, timeout=timeout, cwd=REPO)


@atexit.register
def _close_servers() -> None:
    for server in _SERVERS.values():
        if server is not None:
            server.close()


class Captured:
    """Stands in for a state-dict component of a run: keeps the state the checkpoint holds."""

    def state_dict(self) -> dict:
        return {}

    def load_state_dict(self, state: dict) -> None:
        self.state = state


def saved(run_dir: Path, *names: str) -> dict:
    """The saved state of a run's checkpoint components: ``run`` (a dict), state-dict components
    (``loss``, ``replay``, ``optim_critic``, ...) as their state dicts, ``teacher`` as a buffer."""
    from torchrl.checkpoint import Checkpoint

    from torchrl_sail import TeacherReplayBuffer, TopKTrajectoryWriter

    def holder(name):
        if name == "run":
            return {}
        if name == "teacher":
            return TeacherReplayBuffer(TopKTrajectoryWriter(k=10))
        return Captured()

    components = {name: holder(name) for name in names}
    Checkpoint(**components).load(run_dir / "checkpoint", components=list(names))
    return {name: value.state if isinstance(value, Captured) else value for name, value in components.items()}


def fail_in_process(run_dir: Path, *overrides: str, script: str = "sail_td3.py") -> str:
    """Runs ``script``'s ``main`` in this process on the composed config and returns the error it
    stops with (composition errors included), for input that must fail before training: the same
    code path as the script, without a 5-second interpreter start per case."""
    import importlib

    from hydra import compose, initialize_config_dir
    from hydra.core.hydra_config import HydraConfig
    from omegaconf import open_dict

    if str(EXAMPLES) not in sys.path:
        sys.path.insert(0, str(EXAMPLES))
    module = importlib.import_module(Path(script).stem)
    # the script sets process-wide math state (threads, flush_denormal): put this process's back
    threads, flushing = torch.get_num_threads(), not 5e-324 > 0  # the smallest subnormal reads as 0 when flushed

    try:
        with initialize_config_dir(config_dir=str(REPO / "conf"), version_base="1.3"):
            cfg = compose("config", overrides=[f"hydra.run.dir={run_dir}", *overrides], return_hydra_config=True)
        with open_dict(cfg):
            cfg.hydra.runtime.output_dir = str(run_dir)
        HydraConfig.instance().set_config(cfg)
        Path(run_dir).mkdir(parents=True, exist_ok=True)
        module.main.__wrapped__(cfg)
    except Exception as err:  # noqa: BLE001 (the message is what the tests check)
        return f"{type(err).__name__}: {err}" + (f"\n{err.__cause__}" if err.__cause__ else "")
    finally:
        torch.set_num_threads(threads)
        torch.set_flush_denormal(flushing)
    raise AssertionError(f"{script} {' '.join(overrides)} did not fail")
