"""The paper's teacher demonstrations, downloaded from the SAIL authors' public repository.

The command line is :mod:`torchrl_sail.data.download` (a separate module, so that
``python -m torchrl_sail.data.download`` does not run a module the package has already imported).

The authors published their sub-optimal teachers as stable-baselines ``.npz`` files in
`illidanlab/SAIL <https://github.com/illidanlab/SAIL>`_, folder ``teacher_dataset/``. Each file
is fetched from the raw URL of one pinned commit (:data:`PAPER_TEACHERS_URL`), checked against
its pinned SHA-256 (:data:`PAPER_TEACHERS`), and written atomically (a temporary file in the
destination folder, renamed into place once the checksum matches: a failed or corrupt download
leaves nothing behind). Files already there with the right checksum are not downloaded again.

The files go to a cache folder, :func:`paper_teachers_dir`: ``$TORCHRL_SAIL_TEACHERS`` if set,
else ``$XDG_CACHE_HOME/torchrl_sail/teachers``, else ``~/.cache/torchrl_sail/teachers``.

From the command line (``-h`` for the options)::

    python -m torchrl_sail.data.download            # all 11 files, to paper_teachers_dir()
    python -m torchrl_sail.data.download 'expert_data_no_img_Hopper_*' --dest teachers/
    torchrl-sail-teachers --list                     # the console script (pip install -e .)

then train on one with ``teacher.path=<folder>/expert_data_no_img_Hopper_scores_1500_episodes_1.npz``.
"""

from __future__ import annotations

import argparse
import fnmatch
import hashlib
import http.client
import logging
import os
import sys
import urllib.error
import urllib.parse
import urllib.request
import uuid
from collections.abc import Sequence
from pathlib import Path

__all__ = [
    "PAPER_TEACHERS",
    "PAPER_TEACHERS_COMMIT",
    "PAPER_TEACHERS_URL",
    "TeacherDownloadError",
    "download_paper_teachers",
    "main",
    "missing_paper_teachers",
    "paper_teachers_dir",
]

logger = logging.getLogger(__name__)

#: The commit of ``illidanlab/SAIL`` the files are pinned to (2020-10-06).
PAPER_TEACHERS_COMMIT = "f5612b37739a635d15777d363dd015c394f6de0b"
#: Where the files are downloaded from: ``<PAPER_TEACHERS_URL><file name>``.
PAPER_TEACHERS_URL = f"https://raw.githubusercontent.com/illidanlab/SAIL/{PAPER_TEACHERS_COMMIT}/teacher_dataset/"
#: File name -> SHA-256 of the authors' teacher files at :data:`PAPER_TEACHERS_COMMIT`.
PAPER_TEACHERS: dict[str, str] = {
    "expert_data_no_img_HalfCheetah_scores_5600_episodes_1.npz": "e45ba8de876353b077c874134bf784ca052905df0e9f3a6f0c45b425aac83fd2",
    "expert_data_no_img_HalfCheetah_scores_5600_episodes_10.npz": "99291828afe90ad50ec7bdebcbd02ac33556a11f56299e4c7f66d8d28152681b",
    "expert_data_no_img_HalfCheetah_scores_5600_episodes_4.npz": "87bbece77411862bb9181892e4770a6d896d7791fdac90c36f274680b4e854d3",
    "expert_data_no_img_Hopper_scores_1500_episodes_1.npz": "cd65d7cd690a199bca81d656914b9f9a5d6096ed9466bab944ccbe8b2ba5c31a",
    "expert_data_no_img_Hopper_scores_1500_episodes_10.npz": "85b5c7a9c316f72dbfdac9b6a79066e66519e04a6cf7a1a10b854bef2e6fc1ae",
    "expert_data_no_img_Hopper_scores_1500_episodes_4.npz": "0ffb6004a14f4b80fcdf4f025f821e96ce0974bef58f59749e99dd2d29662565",
    "expert_data_no_img_Swimmer_scores_120_episodes_1.npz": "69cec67bb860de371e898d5d037af1c759e8a746cdb324c4163815ebc6d11ea0",
    "expert_data_no_img_Swimmer_scores_120_episodes_4.npz": "932200ec592939c2813ac5da2176ce0936a6e826d195e9512054645399a26506",
    "expert_data_no_img_Walker2d_scores_1500_episodes_1.npz": "2ba9137d84b0b75d372f8dabeaf82b271d47bbdddcc9712a0abdcb29b65a1937",
    "expert_data_no_img_Walker2d_scores_1500_episodes_10.npz": "5cd964872185e6e7f4978ca97948142764cb32a5d596bb7eefe999c0d91e0e44",
    "expert_data_no_img_Walker2d_scores_1500_episodes_4.npz": "ae2f32d4d9b99b578559f78f6e060a1b84ade13227ffe9f26204557102583b09",
}
_ENV_VAR = "TORCHRL_SAIL_TEACHERS"
_CHUNK = 1 << 16


class TeacherDownloadError(RuntimeError):
    """A teacher file could not be downloaded, or its content does not have the pinned SHA-256."""


def paper_teachers_dir() -> Path:
    """Where the paper's teacher files are cached (the folder may not exist yet).

    ``$TORCHRL_SAIL_TEACHERS`` if set (e.g. a folder that already holds the files), else
    ``$XDG_CACHE_HOME/torchrl_sail/teachers``, else ``~/.cache/torchrl_sail/teachers``.

    Examples:
        >>> import os
        >>> from unittest import mock
        >>> from torchrl_sail.data import paper_teachers_dir
        >>> with mock.patch.dict(os.environ, {"TORCHRL_SAIL_TEACHERS": "/data/sail-teachers"}):
        ...     print(paper_teachers_dir())
        /data/sail-teachers
        >>> with mock.patch.dict(os.environ, {"TORCHRL_SAIL_TEACHERS": "", "XDG_CACHE_HOME": "/cache"}):
        ...     print(paper_teachers_dir())  # (an empty variable counts as unset)
        /cache/torchrl_sail/teachers
    """
    explicit = os.environ.get(_ENV_VAR)
    if explicit:
        return Path(explicit).expanduser()
    cache = os.environ.get("XDG_CACHE_HOME")
    return (Path(cache).expanduser() if cache else Path.home() / ".cache") / "torchrl_sail" / "teachers"


def _select(names: str | Sequence[str] | None) -> list[str]:
    """The file names of ``names`` (file names or ``fnmatch`` patterns), in table order; all if ``None``."""
    if names is None:
        return sorted(PAPER_TEACHERS)
    if isinstance(names, str):
        names = [names]
    selected = []
    for pattern in names:
        matches = fnmatch.filter(sorted(PAPER_TEACHERS), pattern)
        if not matches:
            raise ValueError(
                f"no paper teacher file matches {pattern!r}; the files are: {', '.join(sorted(PAPER_TEACHERS))}."
            )
        selected += [name for name in matches if name not in selected]
    return selected


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        for chunk in iter(lambda: file.read(_CHUNK), b""):
            digest.update(chunk)
    return digest.hexdigest()


def missing_paper_teachers(
    dest: str | os.PathLike | None = None, names: str | Sequence[str] | None = None, *, verify: bool = True
) -> list[str]:
    """The teacher files that are not (or, with ``verify``, not correctly) in ``dest``.

    Args:
        dest: the folder. Defaults to :func:`paper_teachers_dir`.
        names: file names or ``fnmatch`` patterns (``"*Hopper*"``). Defaults to all files.

    Keyword Args:
        verify (bool): also count a file whose SHA-256 is not the pinned one. Defaults to ``True``.

    Returns:
        list[str]: the missing (or corrupt) file names; empty when all are there.

    Examples:
        >>> import tempfile
        >>> from torchrl_sail.data import missing_paper_teachers
        >>> missing_paper_teachers(tempfile.mkdtemp(), "*Swimmer*")
        ['expert_data_no_img_Swimmer_scores_120_episodes_1.npz', 'expert_data_no_img_Swimmer_scores_120_episodes_4.npz']
    """
    folder = paper_teachers_dir() if dest is None else Path(dest).expanduser()
    return [
        name
        for name in _select(names)
        if not (folder / name).is_file() or (verify and _sha256(folder / name) != PAPER_TEACHERS[name])
    ]


def _download(url: str, target: Path, expected: str, timeout: float) -> None:
    """Streams ``url`` to a temporary file beside ``target``, checks its SHA-256, renames it into place."""
    partial = target.with_name(f".{target.name}.{uuid.uuid4().hex[:8]}.part")
    digest, size, announced = hashlib.sha256(), 0, None
    try:
        try:
            with urllib.request.urlopen(url, timeout=timeout) as response, open(partial, "wb") as file:
                announced = response.headers.get("Content-Length")
                for chunk in iter(lambda: response.read(_CHUNK), b""):
                    digest.update(chunk)
                    file.write(chunk)
                    size += len(chunk)
                file.flush()
                os.fsync(file.fileno())
        except urllib.error.HTTPError as err:
            raise TeacherDownloadError(
                f"{target.name}: download failed: HTTP {err.code} {err.reason} from {url}"
            ) from err
        except (OSError, http.client.HTTPException, ValueError) as err:  # URLError, timeout, cut off
            reason = err.reason if isinstance(err, urllib.error.URLError) else err
            raise TeacherDownloadError(
                f"{target.name}: download failed from {url}: {type(err).__name__}: {reason}"
            ) from err
        if announced is not None and announced.isdigit() and int(announced) != size:
            raise TeacherDownloadError(
                f"{target.name}: download from {url} cut off after {size} of {announced} bytes; nothing was written."
            )
        got = digest.hexdigest()
        if got != expected:
            raise TeacherDownloadError(
                f"{target.name}: SHA-256 mismatch for {url}: expected {expected}, got {got}; nothing was written."
            )
        os.replace(partial, target)
    finally:
        partial.unlink(missing_ok=True)


def download_paper_teachers(
    dest: str | os.PathLike | None = None,
    names: str | Sequence[str] | None = None,
    *,
    base_url: str = PAPER_TEACHERS_URL,
    timeout: float = 60.0,
) -> list[Path]:
    """Downloads the SAIL authors' teacher ``.npz`` files (pinned commit, checked SHA-256).

    Each file is fetched from ``base_url + name`` (by default the raw URL of
    ``illidanlab/SAIL`` at :data:`PAPER_TEACHERS_COMMIT`, folder ``teacher_dataset/``),
    streamed to a temporary file in ``dest`` and renamed into place only if its SHA-256 is the
    pinned one of :data:`PAPER_TEACHERS`: a failed or corrupt download leaves no file (and an
    existing one untouched). A file already in ``dest`` with the right SHA-256 is not
    downloaded again; one with another is replaced.

    Args:
        dest: the folder to put them in, created if needed. Defaults to
            :func:`paper_teachers_dir` (``$TORCHRL_SAIL_TEACHERS``, else the user cache).
        names: file names or ``fnmatch`` patterns (``"*Hopper*"``). Defaults to all 11 files.

    Keyword Args:
        base_url (str): the folder URL the names are appended to, e.g. a mirror
            (``https://``, ``http://`` or ``file://``). Defaults to :data:`PAPER_TEACHERS_URL`.
        timeout (float): seconds to wait for the server, per request. Defaults to ``60``.

    Returns:
        list[Path]: the files, in the order of ``names`` (table order for patterns).

    Raises:
        ValueError: a name that matches no teacher file (the message lists them).
        TeacherDownloadError: a download failed (the message names the file, the URL and the
            HTTP status or network error) or its SHA-256 differs (the message names the file,
            the expected and the received hash). Files downloaded before the failure stay.

    Examples:
        >>> import hashlib, pathlib, tempfile
        >>> from torchrl_sail.data import download_paper_teachers, missing_paper_teachers
        >>> from torchrl_sail.data.paper_teachers import TeacherDownloadError
        >>> mirror = pathlib.Path(tempfile.mkdtemp())  # a local mirror, for the example
        >>> name = "expert_data_no_img_Hopper_scores_1500_episodes_1.npz"
        >>> _ = (mirror / name).write_bytes(b"not the real file")
        >>> dest = tempfile.mkdtemp()
        >>> try:
        ...     download_paper_teachers(dest, name, base_url=mirror.as_uri() + "/")
        ... except TeacherDownloadError as err:
        ...     print(str(err)[:60])
        expert_data_no_img_Hopper_scores_1500_episodes_1.npz: SHA-25
        >>> missing_paper_teachers(dest, name)  # nothing was written
        ['expert_data_no_img_Hopper_scores_1500_episodes_1.npz']
    """
    selected = _select(names)
    folder = paper_teachers_dir() if dest is None else Path(dest).expanduser()
    folder.mkdir(parents=True, exist_ok=True)
    base_url = base_url if base_url.endswith("/") else base_url + "/"
    paths = []
    for name in selected:
        target, expected = folder / name, PAPER_TEACHERS[name]
        if target.is_file() and _sha256(target) == expected:
            logger.info("%s: already in %s (SHA-256 ok)", name, folder)
        else:
            if target.exists():
                logger.warning("%s: %s has another SHA-256; downloading it again", name, target)
            url = base_url + urllib.parse.quote(name)
            logger.info("%s: downloading %s", name, url)
            _download(url, target, expected, timeout)
            logger.info("%s: written to %s (SHA-256 ok)", name, target)
        paths.append(target)
    return paths


def main(argv: Sequence[str] | None = None) -> int:
    """The command line: ``python -m torchrl_sail.data.download`` or ``torchrl-sail-teachers``.

    Args:
        argv: the arguments (default: ``sys.argv[1:]``); ``-h`` lists them.

    Returns:
        int: the exit status: 0 on success, 1 on an error (printed to stderr) or, with
        ``--list``, when files are missing.
    """
    parser = argparse.ArgumentParser(
        prog="torchrl-sail-teachers",
        description="Download the SAIL paper's teacher demonstrations (illidanlab/SAIL at commit "
        f"{PAPER_TEACHERS_COMMIT[:12]}), checking each file's pinned SHA-256.",
    )
    parser.add_argument("names", nargs="*", help="file names or patterns, e.g. '*Hopper*' (default: all)")
    parser.add_argument("--dest", help=f"folder (default: ${_ENV_VAR}, else ~/.cache/torchrl_sail/teachers)")
    parser.add_argument("--base-url", default=PAPER_TEACHERS_URL, help="where to download from (a mirror)")
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds per request (default: 60)")
    parser.add_argument("--list", action="store_true", help="list the files and whether they are in --dest")
    args = parser.parse_args(argv)
    folder = paper_teachers_dir() if args.dest is None else Path(args.dest).expanduser()
    try:
        names = _select(args.names or None)
        if args.list:
            missing = set(missing_paper_teachers(folder, names))
            for name in names:
                print(f"{'missing' if name in missing else 'ok     '}  {name}")
            print(f"folder: {folder}")
            return 1 if missing else 0
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(message)s"))
        logger.addHandler(handler)
        previous = logger.level
        logger.setLevel(logging.INFO)
        try:
            paths = download_paper_teachers(folder, names, base_url=args.base_url, timeout=args.timeout)
        finally:
            logger.removeHandler(handler)
            logger.setLevel(previous)
    except (ValueError, TeacherDownloadError, OSError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    print(f"{len(paths)} teacher file{'s' * (len(paths) != 1)} in {folder}")
    return 0
