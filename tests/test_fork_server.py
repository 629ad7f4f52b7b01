"""``tests/fork_server.py``: a script run forked from the pre-imported interpreter sees what ``python <script>``
would (argv, environment, working directory, ``__main__``, ``sys.path``, stdin, output, exit status)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from example_runner import REPO, run_python

PROBE = """
import json, os, sys
print(json.dumps({"argv": sys.argv[1:], "cwd": os.getcwd(), "probe": os.environ.get("PROBE"),
                  "path0": sys.path[0], "path1": sys.path[1], "name": __name__, "file": __file__,
                  "stdin": sys.stdin.read(), "hash": hash("abc")}))
sys.stderr.write("to stderr\\n")
if sys.argv[1] == "raise":
    raise KeyError("from the script")
if sys.argv[1] == "sleep":
    import time
    time.sleep(60)
sys.exit(int(sys.argv[1]))
"""


@pytest.fixture
def probe(tmp_path):
    path = tmp_path / "probe.py"
    path.write_text(PROBE)
    return path


pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the fork server runs on Linux only")


@pytest.mark.parametrize("fork", ["1", "0"])  # the fork server, and plain python for reference
def test_a_run_sees_what_python_gives_a_script(probe, monkeypatch, fork):
    monkeypatch.setenv("TORCHRL_SAIL_TESTS_FORK", fork)
    extra = str(probe.parent / "lib")
    proc = run_python([str(probe), "3", "--x=y"], env={**os.environ, "PROBE": "set", "PYTHONPATH": extra}, timeout=120)
    assert proc.returncode == 3 and proc.stderr == "to stderr\n"
    seen = json.loads(proc.stdout)
    del seen["hash"]  # random per interpreter unless PYTHONHASHSEED sets it (the next test)
    assert seen == {
        "argv": ["3", "--x=y"],
        "cwd": str(REPO),
        "probe": "set",
        "path0": str(probe.parent),
        "path1": extra,
        "name": "__main__",
        "file": str(probe),
        "stdin": "",
    }
    failed = run_python([str(probe), "raise"], env=dict(os.environ), timeout=120)
    assert failed.returncode == 1 and failed.stderr.startswith("to stderr\nTraceback (most recent call last):")
    assert failed.stderr.endswith("KeyError: 'from the script'\n")


def test_a_run_with_other_startup_variables_runs_as_python_would(probe, monkeypatch):
    # PYTHONHASHSEED is read when an interpreter starts: the server's cannot serve another value
    monkeypatch.setenv("TORCHRL_SAIL_TESTS_FORK", "1")
    monkeypatch.delenv("PYTHONHASHSEED", raising=False)
    env = {**os.environ, "PYTHONHASHSEED": "123"}
    expected = subprocess.run([sys.executable, "-c", "print(hash('abc'))"], env=env, capture_output=True, text=True)
    proc = run_python([str(probe), "0"], env=env, timeout=120)
    assert json.loads(proc.stdout)["hash"] == int(expected.stdout)


def test_a_run_past_its_timeout_is_killed(probe):
    with pytest.raises(subprocess.TimeoutExpired):
        run_python([str(probe), "sleep"], env=dict(os.environ), timeout=3)
    # the server goes on serving
    assert run_python([str(probe), "0"], env=dict(os.environ), timeout=120).returncode == 0


def test_the_server_has_torch_imported_and_each_run_its_own_process(probe, monkeypatch):
    monkeypatch.setenv("TORCHRL_SAIL_TESTS_FORK", "1")
    script = probe.parent / "pid.py"
    script.write_text("import os, sys; print(os.getpid(), 'torch' in sys.modules)")
    first, second = (run_python([str(script)], env=dict(os.environ), timeout=120).stdout.split() for _ in range(2))
    assert first[1] == second[1] == "True" and first[0] != second[0] != str(os.getpid())
