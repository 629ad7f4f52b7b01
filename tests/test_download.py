"""Tests for torchrl_sail.data.paper_teachers (the paper's teacher files: download, cache, checks).

Everything is served by a local HTTP server on 127.0.0.1: nothing is fetched from the internet.
"""

from __future__ import annotations

import functools
import hashlib
import http.server
import runpy
import shutil
import socket
import sys
import threading
import urllib.error
import urllib.request
import warnings
from pathlib import Path

import pytest

from torchrl_sail import load_demonstrations
from torchrl_sail.data import (
    download_paper_teachers,
    missing_paper_teachers,
    paper_teachers,
    paper_teachers_dir,
)
from torchrl_sail.data.paper_teachers import (
    OTHER_TEACHERS,
    PAPER_TEACHERS,
    PAPER_TEACHERS_URL,
    TEACHER_ENVS,
    TeacherDownloadError,
    _select,
    main,
    teacher_env,
)

HOPPER_1 = "expert_data_no_img_Hopper_scores_1500_episodes_1.npz"
FAKE = {"teacher_a.npz": b"a" * 100_000, "teacher_b.npz": b"b" * 10}


class _Handler(http.server.SimpleHTTPRequestHandler):
    """Serves a folder; records each request; cuts off the body of the files in ``truncate``."""

    def __init__(self, *args, requests, truncate, **kwargs):
        self.requests, self.truncate = requests, truncate
        super().__init__(*args, **kwargs)

    def do_GET(self):  # noqa: N802 (http.server's name)
        self.requests.append(self.path)
        name = self.path.lstrip("/")
        if name in self.truncate:
            body = (Path(self.directory) / name).read_bytes()
            self.send_response(200)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body[: len(body) // 2])
            self.wfile.flush()
            self.close_connection = True
            return
        super().do_GET()

    def log_message(self, *args):
        pass


class _Server:
    def __init__(self, folder: Path):
        self.folder, self.requests, self.truncate = folder, [], set()
        handler = functools.partial(_Handler, directory=str(folder), requests=self.requests, truncate=self.truncate)
        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/"
        self.thread = threading.Thread(target=self.httpd.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
        self.thread.start()

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join()


@pytest.fixture
def server(tmp_path, monkeypatch):
    """A local HTTP server of ``tmp_path/served``, reached without any proxy."""
    for var in ("http_proxy", "HTTP_PROXY", "https_proxy", "HTTPS_PROXY", "all_proxy", "ALL_PROXY"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("no_proxy", "127.0.0.1,localhost")
    folder = tmp_path / "served"
    folder.mkdir()
    server = _Server(folder)
    yield server
    server.close()


@pytest.fixture
def fake_table(server, monkeypatch):
    """Small fake teacher files served by ``server``, with their hashes as the pinned table."""
    for name, content in FAKE.items():
        (server.folder / name).write_bytes(content)
    table = {name: hashlib.sha256(content).hexdigest() for name, content in FAKE.items()}
    monkeypatch.setattr(paper_teachers, "PAPER_TEACHERS", table)
    monkeypatch.setattr(paper_teachers, "OTHER_TEACHERS", {})
    return table


def _files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def test_download_then_cache_hit(server, fake_table, tmp_path):
    dest = tmp_path / "cache" / "teachers"  # created
    paths = download_paper_teachers(dest, ["teacher_b.npz", "teacher_a.npz"], base_url=server.url)
    assert paths == [dest / "teacher_b.npz", dest / "teacher_a.npz"]  # in the order asked
    assert all(path.read_bytes() == FAKE[path.name] for path in paths)
    assert sorted(server.requests) == ["/teacher_a.npz", "/teacher_b.npz"]
    assert _files(dest) == ["teacher_a.npz", "teacher_b.npz"]  # no temporary file left
    assert missing_paper_teachers(dest) == []

    # already there with the right hash: no request at all (names=None: every file)
    assert download_paper_teachers(dest, base_url=server.url) == [dest / "teacher_a.npz", dest / "teacher_b.npz"]
    assert len(server.requests) == 2


def test_default_destination_is_the_cache(server, fake_table, tmp_path, monkeypatch):
    monkeypatch.setenv("TORCHRL_SAIL_TEACHERS", str(tmp_path / "env-folder"))
    download_paper_teachers(names="teacher_b.npz", base_url=server.url.rstrip("/"))  # a base URL without "/"
    assert _files(tmp_path / "env-folder") == ["teacher_b.npz"]


def test_bad_checksum_leaves_nothing(server, fake_table, tmp_path):
    (server.folder / "teacher_a.npz").write_bytes(b"tampered")
    dest = tmp_path / "dest"
    with pytest.raises(TeacherDownloadError) as err:
        download_paper_teachers(dest, "teacher_a.npz", base_url=server.url)
    message = str(err.value)
    assert message.startswith("teacher_a.npz: SHA-256 mismatch for " + server.url + "teacher_a.npz")
    assert f"expected {fake_table['teacher_a.npz']}" in message
    assert f"got {hashlib.sha256(b'tampered').hexdigest()}" in message
    assert _files(dest) == []


def test_404_is_a_clear_error(server, fake_table, tmp_path):
    (server.folder / "teacher_b.npz").unlink()
    dest = tmp_path / "dest"
    with pytest.raises(
        TeacherDownloadError,
        match=rf"teacher_b\.npz: download failed: HTTP 404 .* from "
        rf"{server.url}teacher_b\.npz",
    ):
        download_paper_teachers(dest, base_url=server.url)
    # teacher_a (first in table order) was downloaded and stays; nothing of teacher_b
    assert _files(dest) == ["teacher_a.npz"]


def test_cut_off_download_leaves_nothing(server, fake_table, tmp_path):
    server.truncate.add("teacher_a.npz")
    dest = tmp_path / "dest"
    with pytest.raises(
        TeacherDownloadError,
        match=r"teacher_a\.npz: download from .* cut off after 50000 of "
        r"100000 bytes; nothing was written",
    ):
        download_paper_teachers(dest, "teacher_a.npz", base_url=server.url)
    assert _files(dest) == []


def test_unreachable_server(fake_table, tmp_path):
    with socket.socket() as sock:  # a port nothing listens on once closed
        sock.bind(("127.0.0.1", 0))
        url = f"http://127.0.0.1:{sock.getsockname()[1]}/"
    with pytest.raises(TeacherDownloadError, match=r"teacher_b\.npz: download failed from .*refused"):
        download_paper_teachers(tmp_path / "dest", "teacher_b.npz", base_url=url, timeout=5)
    assert _files(tmp_path / "dest") == []


def test_corrupt_cached_file_is_downloaded_again(server, fake_table, tmp_path):
    dest = tmp_path / "dest"
    dest.mkdir()
    (dest / "teacher_a.npz").write_bytes(b"half a fi")
    assert missing_paper_teachers(dest) == ["teacher_a.npz", "teacher_b.npz"]
    assert missing_paper_teachers(dest, verify=False) == ["teacher_b.npz"]
    download_paper_teachers(dest, "teacher_a.npz", base_url=server.url)
    assert (dest / "teacher_a.npz").read_bytes() == FAKE["teacher_a.npz"]
    # a failing download leaves the file that was there as it was
    (dest / "teacher_a.npz").write_bytes(b"half a fi")
    (server.folder / "teacher_a.npz").write_bytes(b"tampered")
    with pytest.raises(TeacherDownloadError, match="SHA-256 mismatch"):
        download_paper_teachers(dest, "teacher_a.npz", base_url=server.url)
    assert (dest / "teacher_a.npz").read_bytes() == b"half a fi" and _files(dest) == ["teacher_a.npz"]


def test_names_and_patterns():
    hopper = _select("*_Hopper_*")
    assert hopper == sorted(name for name in PAPER_TEACHERS if "_Hopper_" in name) and len(hopper) == 3
    with pytest.raises(
        ValueError,
        match=r"no paper teacher file matches 'Hoper\*'; the files are: "
        r"expert_data_no_img_Ant",
    ):
        download_paper_teachers(names="Hoper*")
    assert len(PAPER_TEACHERS) == 11


def test_the_default_url_is_the_pinned_commit(tmp_path, monkeypatch):
    assert PAPER_TEACHERS_URL == (
        "https://raw.githubusercontent.com/illidanlab/SAIL/f5612b37739a635d15777d363dd015c394f6de0b/teacher_dataset/"
    )
    asked = []

    def offline(url, timeout):  # no network here: record the URL and fail as a network error would
        asked.append(url)
        raise urllib.error.URLError("offline")

    monkeypatch.setattr(urllib.request, "urlopen", offline)
    with pytest.raises(TeacherDownloadError, match=rf"{HOPPER_1}: download failed from .*: URLError: offline"):
        download_paper_teachers(tmp_path, HOPPER_1)
    assert asked == [PAPER_TEACHERS_URL + HOPPER_1]
    assert _files(tmp_path) == []


def test_paper_teachers_dir(monkeypatch, tmp_path):
    monkeypatch.setenv("TORCHRL_SAIL_TEACHERS", str(tmp_path / "teachers"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert paper_teachers_dir() == tmp_path / "teachers"
    monkeypatch.delenv("TORCHRL_SAIL_TEACHERS")
    assert paper_teachers_dir() == tmp_path / "xdg" / "torchrl_sail" / "teachers"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert paper_teachers_dir() == tmp_path / "home" / ".cache" / "torchrl_sail" / "teachers"


def test_real_file_from_a_local_mirror(server, teacher_dir, tmp_path):
    shutil.copy(teacher_dir / HOPPER_1, server.folder / HOPPER_1)
    dest = tmp_path / "dest"
    (path,) = download_paper_teachers(dest, HOPPER_1, base_url=server.url)  # the real pinned hash
    assert path.read_bytes() == (teacher_dir / HOPPER_1).read_bytes()
    assert load_demonstrations(path).metadata["episode_lengths"] == [425]
    assert missing_paper_teachers(dest, "*Hopper*") == [
        "expert_data_no_img_Hopper_scores_1500_episodes_10.npz",
        "expert_data_no_img_Hopper_scores_1500_episodes_4.npz",
    ]


def test_command_line(server, fake_table, tmp_path, capsys):
    dest = tmp_path / "dest"
    assert main(["--list", "--dest", str(dest)]) == 1
    assert capsys.readouterr().out.splitlines()[:2] == ["missing  teacher_a.npz", "missing  teacher_b.npz"]
    assert main(["teacher_a.npz", "--dest", str(dest), "--base-url", server.url]) == 0
    out, err = capsys.readouterr()
    assert out == f"1 teacher file in {dest}\n" and "teacher_a.npz: downloading" in err
    assert main(["--dest", str(dest), "--base-url", server.url]) == 0
    assert "teacher_a.npz: already in" in capsys.readouterr().err
    assert main(["--list", "--dest", str(dest)]) == 0
    (server.folder / "teacher_a.npz").unlink()
    (dest / "teacher_a.npz").unlink()
    assert main(["--dest", str(dest), "--base-url", server.url]) == 1
    assert "error: teacher_a.npz: download failed: HTTP 404" in capsys.readouterr().err


def test_python_dash_m(tmp_path, monkeypatch, capsys):
    # what `python -m torchrl_sail.data.download --list '*Swimmer*'` runs, in this process
    monkeypatch.setenv("TORCHRL_SAIL_TEACHERS", str(tmp_path))
    monkeypatch.setattr(sys, "argv", ["download", "--list", "*Swimmer*"])
    monkeypatch.delitem(sys.modules, "torchrl_sail.data.download", raising=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. runpy's "found in sys.modules after import of package"
        with pytest.raises(SystemExit) as exit_:
            runpy.run_module("torchrl_sail.data.download", run_name="__main__", alter_sys=True)
    assert exit_.value.code == 1  # missing files
    swimmer_50 = "  (recorded without the time feature (8 columns): it is appended on loading, computed from the steps)"
    assert capsys.readouterr().out.splitlines() == [
        "missing  expert_data_no_img_Swimmer_scores_120_episodes_1.npz  env=Swimmer-v4",
        "missing  expert_data_no_img_Swimmer_scores_120_episodes_4.npz  env=Swimmer-v4",
        "missing  expert_data_no_img_Swimmer_scores_50_episodes_1.npz  env=Swimmer-v4" + swimmer_50,
        "missing  expert_data_no_img_Swimmer_scores_50_episodes_4.npz  env=Swimmer-v4" + swimmer_50,
        f"folder: {tmp_path}",
    ]


def test_every_published_file_names_an_env_with_its_settings():
    """The 20 files of the authors' folder: each loads into an env this package configures."""
    assert len({**PAPER_TEACHERS, **OTHER_TEACHERS}) == 20 and not set(PAPER_TEACHERS) & set(OTHER_TEACHERS)
    conf = Path(__file__).resolve().parents[1] / "conf" / "env"
    for name in {**PAPER_TEACHERS, **OTHER_TEACHERS}:
        env, _ = teacher_env(name)
        assert (conf / f"{env}.yaml").is_file(), name
    assert {env for env, _ in TEACHER_ENVS.values()} == {
        f"{env}-v4" for env in ("HalfCheetah", "Hopper", "Walker2d", "Swimmer", "Ant", "Humanoid", "Reacher")
    }
    assert teacher_env("teacher_a.npz") is None


def test_a_file_pinned_by_its_git_blob_id(server, tmp_path, monkeypatch):
    """A pin ``git-blob:<sha1>`` is checked as git names the file: SHA-1 of "blob <size>\\0" + content."""
    content = b"an Ant teacher"
    # what `git hash-object` prints for this content
    blob = hashlib.sha1(b"blob 14\0" + content).hexdigest()
    (server.folder / "teacher_c.npz").write_bytes(content)
    monkeypatch.setattr(paper_teachers, "PAPER_TEACHERS", {})
    monkeypatch.setattr(paper_teachers, "OTHER_TEACHERS", {"teacher_c.npz": f"git-blob:{blob}"})
    (path,) = download_paper_teachers(tmp_path / "dest", "teacher_c.npz", base_url=server.url)
    assert path.read_bytes() == content and missing_paper_teachers(tmp_path / "dest", "teacher_c.npz") == []
    (server.folder / "teacher_c.npz").write_bytes(b"another Ant file")
    with pytest.raises(
        TeacherDownloadError, match=rf"teacher_c\.npz: git blob id mismatch .* expected git-blob:{blob}"
    ):
        download_paper_teachers(tmp_path / "other", "teacher_c.npz", base_url=server.url)
    assert _files(tmp_path / "other") == []


def test_a_refused_published_file_says_why_and_the_same_data_under_another_name_loads(tmp_path):
    import numpy as np

    t = np.arange(3)
    obs = np.stack([np.full(3, 0.5), 1 - t / 1000], axis=1).astype("float32")
    starts = np.empty(3, dtype=object)
    starts[:] = [True, np.array([False]), np.array([False])]
    arrays = {
        "obs": obs,
        "actions": np.zeros((3, 1), "float32"),
        "rewards": np.ones((3, 1), "float32"),
        "episode_returns": np.array([3.0]),
        "episode_starts": starts,
    }
    refused = tmp_path / "expert_data_no_img_Humanoid_scores_500_episodes_1.npz"
    np.savez(refused, **arrays)
    with pytest.raises(
        ValueError,
        match=r"Humanoid_scores_500_episodes_1\.npz: this published SAIL teacher file is "
        r"refused: its observations and rewards were recorded normalised",
    ):
        load_demonstrations(refused)
    other = tmp_path / "humanoid_demo.npz"
    np.savez(other, **arrays)
    assert load_demonstrations(other).metadata["episode_returns"] == [3.0]
