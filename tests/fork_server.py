"""Runs the example scripts as processes forked from an interpreter that has already imported
torch, tensordict, TorchRL, torchrl_sail and matplotlib's Agg figure (shared by the example tests
through ``example_runner``).

A script started with ``python examples/<script>`` spends ~5 s importing them before its first
line. The server pays that once per test process; each run is then a fork of it: a process of
its own with the script's ``argv``, environment, working directory, output files and exit
status, as ``python <script>`` has them (``sys.path[0]`` is the script's folder, then the
entries of the run's ``PYTHONPATH``; the script runs as ``__main__``, stdin is ``/dev/null``, the
interpreter exits normally). What an interpreter reads when it starts or imports torch is the
server's: :data:`STARTUP_VARIABLES` and ``MUJOCO_GL`` (TorchRL imports MuJoCo, which reads it), so a
server serves one ``MUJOCO_GL`` value, and ``example_runner`` runs a script plainly when its
environment differs from the server's in the others.

The protocol is one JSON line per request on the server's stdin: ``{"argv", "env", "cwd",
"stdout", "stderr"}``; it answers ``{"pid"}`` once the run has started, then
``{"returncode"}`` when it has ended.
"""

from __future__ import annotations

import json
import os
import runpy
import select
import signal
import subprocess
import sys
import time
import traceback
from pathlib import Path

PRELOAD = (
    "torch",
    "tensordict",
    "torchrl.envs",
    "torchrl.collectors",
    "torchrl.objectives",
    "torchrl.modules",
    "hydra",
    "torchrl_sail",  # the installed package: a run whose PYTHONPATH holds another copy still gets this one
    "matplotlib.figure",  # learning_curve.png: a Figure rendered by Agg, no pyplot (no backend chosen)
    "matplotlib.backends.backend_agg",
)


#: Read by the interpreter or by torch's import, so fixed in the server (``PYTHONPATH`` is applied per run).
STARTUP_VARIABLES = (
    "PYTHONHASHSEED",
    "PYTHONWARNINGS",
    "PYTHONDONTWRITEBYTECODE",
    "PYTHONOPTIMIZE",
    "PYTHONSAFEPATH",
    "PYTHONNOUSERSITE",
    "PYTHONUSERBASE",
    "PYTHONHOME",
    "PYTHONSTARTUP",
    "PYTHONMALLOC",
    "PYTHONUTF8",
    "PYTHONIOENCODING",
    "PYTHONDEVMODE",
    "PYTHONFAULTHANDLER",
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
)


class ServerGone(RuntimeError):
    """The server process has exited (e.g. its imports failed): nothing can run through it."""


class ForkServer:
    """The client: starts ``python fork_server.py`` with ``env`` and runs scripts through it."""

    def __init__(self, env: dict):
        self.process = subprocess.Popen(
            [sys.executable, __file__],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=env,
            bufsize=0,
        )
        self._pending = b""  # answers read but not yet consumed

    def run(self, argv: list[str], *, env: dict, cwd: Path, timeout: float, out_dir: Path):
        """Runs ``argv`` (``[script, *args]``) in a fork; returns a ``subprocess.CompletedProcess``
        with the text the run wrote to stdout and stderr, or raises ``subprocess.TimeoutExpired``."""
        out_dir.mkdir(parents=True, exist_ok=True)
        stdout, stderr = out_dir / "stdout", out_dir / "stderr"
        request = {"argv": argv, "env": env, "cwd": str(cwd), "stdout": str(stdout), "stderr": str(stderr)}
        try:
            self.process.stdin.write((json.dumps(request) + "\n").encode())
        except BrokenPipeError:
            raise ServerGone(f"the fork server exited (status {self.process.wait()})") from None
        pid = json.loads(self._answer(600))["pid"]
        try:
            returncode = json.loads(self._answer(timeout))["returncode"]
        except TimeoutError:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:  # it ended as the time ran out (and was reaped): its answer is on the way
                returncode = json.loads(self._answer(60))["returncode"]
            else:
                self._answer(60)
                raise subprocess.TimeoutExpired(
                    argv, timeout, stdout.read_text(errors="replace"), stderr.read_text(errors="replace")
                ) from None
        except ServerGone as gone:  # the run had started: running it again would reuse its folder
            raise RuntimeError(f"the fork server exited during the run of {argv}: {gone}") from None
        return subprocess.CompletedProcess(
            [sys.executable, *argv], returncode, stdout.read_text(errors="replace"), stderr.read_text(errors="replace")
        )

    def _answer(self, timeout: float) -> str:
        """The server's next answer line, waiting at most ``timeout`` seconds (then ``TimeoutError``)."""
        deadline = time.monotonic() + timeout
        while b"\n" not in self._pending:
            ready, _, _ = select.select([self.process.stdout], [], [], max(0.0, deadline - time.monotonic()))
            if not ready:
                raise TimeoutError
            chunk = os.read(self.process.stdout.fileno(), 65536)
            if not chunk:
                raise ServerGone(f"the fork server exited (status {self.process.wait()})")
            self._pending += chunk
        line, _, self._pending = self._pending.partition(b"\n")
        return line.decode()

    def close(self) -> None:
        try:
            self.process.stdin.close()
            self.process.wait(timeout=60)
        except (OSError, subprocess.TimeoutExpired):
            self.process.kill()


def _run_script(request: dict) -> int:
    """In the fork: becomes ``python <argv>`` and runs the script; returns its exit status."""
    out = os.open(request["stdout"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
    err = os.open(request["stderr"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
    os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
    sys.stdin = open(0, closefd=False)  # noqa: SIM115 (the process's stdin, as the interpreter opens it)
    os.dup2(out, 1)
    os.dup2(err, 2)
    os.environ.clear()
    os.environ.update(request["env"])
    os.chdir(request["cwd"])
    script = os.path.abspath(request["argv"][0])
    sys.argv = list(request["argv"])
    sys.path[0] = os.path.dirname(script)
    sys.path[1:1] = [entry for entry in request["env"].get("PYTHONPATH", "").split(os.pathsep) if entry]
    try:
        runpy.run_path(script, run_name="__main__")
    except SystemExit as exit_:
        code = exit_.code
        if code is None or isinstance(code, int):
            return code or 0
        print(code, file=sys.stderr)
        return 1
    except BaseException:  # noqa: BLE001 (as the interpreter does: the traceback, status 1)
        traceback.print_exc()
        return 1
    return 0


def serve() -> int | None:
    """The server's loop; returns the exit status in a fork (which then leaves the loop)."""
    import importlib

    # answers on a descriptor of their own: what an import prints to stdout goes to stderr instead
    answers = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    for name in PRELOAD:
        importlib.import_module(name)
    for line in sys.stdin:
        request = json.loads(line)
        pid = os.fork()
        if pid == 0:
            sys.stdin.close()
            answers.close()
            return _run_script(request)
        answers.write(json.dumps({"pid": pid}) + "\n")
        answers.flush()
        _, status = os.waitpid(pid, 0)
        answers.write(json.dumps({"returncode": os.waitstatus_to_exitcode(status)}) + "\n")
        answers.flush()
    return None


if __name__ == "__main__":
    code = serve()
    if code is not None:
        sys.stdout.flush()
        sys.stderr.flush()
        sys.exit(code)
