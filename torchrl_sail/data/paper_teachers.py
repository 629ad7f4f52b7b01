"""The paper's teacher demonstrations, downloaded from the SAIL authors' public repository.

The command line is :mod:`torchrl_sail.data.download` (a separate module, so that
``python -m torchrl_sail.data.download`` does not run a module the package has already imported).

The authors published their sub-optimal teachers as stable-baselines ``.npz`` files in
`illidanlab/SAIL <https://github.com/illidanlab/SAIL>`_, folder ``teacher_dataset/``: the paper's
four envs (:data:`PAPER_TEACHERS`) and, beside them, Ant, Humanoid, Reacher and a second Swimmer
teacher (:data:`OTHER_TEACHERS`). Each file is fetched from the raw URL of one pinned commit
(:data:`PAPER_TEACHERS_URL`), checked against its pin (its SHA-256; for the one file whose content
was not at hand when it was pinned, its git blob id, ``git-blob:<sha1>``, the SHA-1 that git's
tree at the pinned commit names it by), and written atomically (a temporary file in the
destination folder, renamed into place once the checksum matches: a failed or corrupt download
leaves nothing behind). Files already there with the right checksum are not downloaded again.
:data:`TEACHER_ENVS` says which env each file loads into, with which settings
(``conf/env/<env>.yaml``), and what of its recording the env does not reproduce;
:data:`REPRODUCED_COLUMNS`, how to train on the rest alone.

The files go to a cache folder, :func:`paper_teachers_dir`: ``$TORCHRL_SAIL_TEACHERS`` if set,
else ``$XDG_CACHE_HOME/torchrl_sail/teachers``, else ``~/.cache/torchrl_sail/teachers``.

From the command line (``-h`` for the options)::

    python -m torchrl_sail.data.download            # all 20 files, to paper_teachers_dir()
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
    "OTHER_TEACHERS",
    "PAPER_TEACHERS",
    "REFUSED_TEACHERS",
    "REPRODUCED_COLUMNS",
    "TEACHER_ENVS",
    "PAPER_TEACHERS_COMMIT",
    "PAPER_TEACHERS_URL",
    "TeacherDownloadError",
    "download_paper_teachers",
    "main",
    "missing_paper_teachers",
    "paper_teachers_dir",
    "refused_teacher",
    "reproduced_columns",
    "teacher_env",
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
#: The other files of the same folder and commit, which the paper's experiments do not use.
OTHER_TEACHERS: dict[str, str] = {
    "expert_data_no_img_Ant_scores_1200_episodes_1.npz": "cd7ba0cab93676d317883e3e7e8f2bf35d6b38705bf02d72deca6f9218061a20",
    "expert_data_no_img_Ant_scores_1200_episodes_10.npz": "git-blob:69b03f2e0f7d889f79d10a942517fd47866b32da",
    "expert_data_no_img_Ant_scores_1200_episodes_4.npz": "3d7a953724764ce19434cc257c48052fe57f6d0b66ee45b8b0895b6e81b1b953",
    "expert_data_no_img_Humanoid_scores_500_episodes_1.npz": "b24b1f618a74c7ed6b4180e1ec5376c8716e1480c43a9d9b5cb8601d3c34f978",
    "expert_data_no_img_Humanoid_scores_500_episodes_4.npz": "10ce986d795a21b6710c9147e10236385819d51900dc08a277cea70f31b058a2",
    "expert_data_no_img_Reacher_scores_-3.6_episodes_1.npz": "4f3f5defaaa43bc865f9e624f31b96b1c22b460609b066b0f1b02d8ac29a8116",
    "expert_data_no_img_Reacher_scores_-3.6_episodes_4.npz": "a48cb376e2f921de8ce654324245c654798546bf9307b3fd246ef32bac2871da",
    "expert_data_no_img_Swimmer_scores_50_episodes_1.npz": "408f6c591621c350db6da565779cf2057d86e28135509915bc061cef74d545a6",
    "expert_data_no_img_Swimmer_scores_50_episodes_4.npz": "016b0ac2e38468eba6558aedd46f48f900319589268afa8e074573fd8caf0c27",
}
#: Per file-name prefix (``expert_data_no_img_<Env>_scores_<score>``): the env the files load into
#: (``env=<env>``, whose ``conf/env`` file holds the authors' settings and env kwargs) and what of
#: the recording that env does not reproduce ("" where it reproduces every column).
TEACHER_ENVS: dict[str, tuple[str, str]] = {
    "expert_data_no_img_HalfCheetah_scores_5600": ("HalfCheetah-v4", ""),
    "expert_data_no_img_Hopper_scores_1500": ("Hopper-v4", ""),
    "expert_data_no_img_Walker2d_scores_1500": ("Walker2d-v4", ""),
    "expert_data_no_img_Swimmer_scores_120": ("Swimmer-v4", ""),
    "expert_data_no_img_Swimmer_scores_50": (
        "Swimmer-v4",
        "recorded without the time feature (8 columns): it is appended on loading, computed from the steps",
    ),
    "expert_data_no_img_Ant_scores_1200": (
        "Ant-v4",
        "111 columns + the time feature, with contact forces (use_contact_forces=true); columns 27-110, the "
        "contact forces, are 0.0 in every row (mujoco-py 2.x reported none), where Ant-v4 fills them",
    ),
    "expert_data_no_img_Humanoid_scores_500": ("Humanoid-v4", ""),  # refused: REFUSED_TEACHERS
    "expert_data_no_img_Reacher_scores_-3.6": ("Reacher-v4", "episodes of 50 steps: the time feature is 1 - t/50"),
}
#: Per file-name prefix where the env does not reproduce some columns: the settings that train those
#: files on the columns it does (``teacher.drop_columns`` and the env kwargs that make the env match).
REPRODUCED_COLUMNS: dict[str, str] = {
    "expert_data_no_img_Ant_scores_1200": "teacher.drop_columns=27-110 env.kwargs.use_contact_forces=false",
}
#: Per file-name prefix: why those files are refused on loading (no env reproduces their recording).
REFUSED_TEACHERS: dict[str, str] = {
    "expert_data_no_img_Humanoid_scores_500": (
        "its observations and rewards were recorded normalised, which no env reproduces: the torso "
        "quaternion's first component reads 1.044 (above 1) and the torso height 2.32 at an episode's first "
        "step, where Humanoid starts near 1.4; the time column runs from 1.41 to -1.11; the rewards are about "
        "0.04 a step, where Humanoid pays about 5 (returns 4.3-6.4 over episodes of about 105 steps)"
    ),
}
_GIT_BLOB = "git-blob:"
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


def _published() -> dict[str, str]:
    """Every published file's pin: the paper's envs', then the others'."""
    return {**PAPER_TEACHERS, **OTHER_TEACHERS}


def teacher_env(name: str) -> tuple[str, str] | None:
    """The env a published teacher file loads into and what of its recording the env does not
    reproduce (:data:`TEACHER_ENVS`); ``None`` for another file name.

    Examples:
        >>> teacher_env("expert_data_no_img_Ant_scores_1200_episodes_4.npz")[0]
        'Ant-v4'
    """
    return TEACHER_ENVS.get(name.rsplit("_episodes_", 1)[0])


def reproduced_columns(name: str) -> str | None:
    """The settings that train the published teacher file ``name`` on only the columns its env
    reproduces (:data:`REPRODUCED_COLUMNS`), or ``None`` where there are none to drop or ``name`` is
    another file.

    Examples:
        >>> reproduced_columns("expert_data_no_img_Ant_scores_1200_episodes_1.npz")
        'teacher.drop_columns=27-110 env.kwargs.use_contact_forces=false'
    """
    return REPRODUCED_COLUMNS.get(name.rsplit("_episodes_", 1)[0])


def refused_teacher(name: str) -> str | None:
    """Why the published teacher file ``name`` is refused on loading (:data:`REFUSED_TEACHERS`), or ``None``.

    Examples:
        >>> refused_teacher("expert_data_no_img_Hopper_scores_1500_episodes_1.npz") is None
        True
    """
    return REFUSED_TEACHERS.get(name.rsplit("_episodes_", 1)[0])


def _select(names: str | Sequence[str] | None, table: Sequence[str] | None = None) -> list[str]:
    """The file names of ``names`` (file names or ``fnmatch`` patterns) among ``table`` (default: every
    published file), in table order; all of ``table`` if ``None``."""
    table = sorted(_published() if table is None else table)
    if names is None:
        return table
    if isinstance(names, str):
        names = [names]
    selected = []
    for pattern in names:
        matches = fnmatch.filter(table, pattern)
        if not matches:
            raise ValueError(f"no paper teacher file matches {pattern!r}; the files are: {', '.join(table)}.")
        selected += [name for name in matches if name not in selected]
    return selected


def _digest(path: Path, pin: str) -> str:
    """``path``'s checksum of the kind ``pin`` is: its SHA-256, or for ``git-blob:<sha1>`` its git blob id
    (``git-blob:`` + the SHA-1 of ``b"blob <size>\\0"`` and the content)."""
    if pin.startswith(_GIT_BLOB):
        digest = hashlib.sha1(f"blob {path.stat().st_size}\0".encode(), usedforsecurity=False)
    else:
        digest = hashlib.sha256()
    with open(path, "rb") as file:
        for chunk in iter(lambda: file.read(_CHUNK), b""):
            digest.update(chunk)
    return (_GIT_BLOB if pin.startswith(_GIT_BLOB) else "") + digest.hexdigest()


def _checksum_name(pin: str) -> str:
    return "git blob id" if pin.startswith(_GIT_BLOB) else "SHA-256"


def missing_paper_teachers(
    dest: str | os.PathLike | None = None, names: str | Sequence[str] | None = None, *, verify: bool = True
) -> list[str]:
    """The teacher files that are not (or, with ``verify``, not correctly) in ``dest``.

    Args:
        dest: the folder. Defaults to :func:`paper_teachers_dir`.
        names: file names or ``fnmatch`` patterns (``"*Hopper*"``) among every published file.
            Defaults to the files of the paper's four envs (:data:`PAPER_TEACHERS`).

    Keyword Args:
        verify (bool): also count a file whose checksum is not the pinned one. Defaults to ``True``.

    Returns:
        list[str]: the missing (or corrupt) file names; empty when all are there.

    Examples:
        >>> import tempfile
        >>> from torchrl_sail.data import missing_paper_teachers
        >>> missing_paper_teachers(tempfile.mkdtemp(), "*Swimmer_scores_120*")
        ['expert_data_no_img_Swimmer_scores_120_episodes_1.npz', 'expert_data_no_img_Swimmer_scores_120_episodes_4.npz']
    """
    folder = paper_teachers_dir() if dest is None else Path(dest).expanduser()
    pins = _published()
    selected = _select(None, PAPER_TEACHERS) if names is None else _select(names)
    return [
        name
        for name in selected
        if not (folder / name).is_file() or (verify and _digest(folder / name, pins[name]) != pins[name])
    ]


def _download(url: str, target: Path, expected: str, timeout: float) -> None:
    """Streams ``url`` to a temporary file beside ``target``, checks it against the pin ``expected``,
    renames it into place."""
    partial = target.with_name(f".{target.name}.{uuid.uuid4().hex[:8]}.part")
    size, announced = 0, None
    try:
        try:
            with urllib.request.urlopen(url, timeout=timeout) as response, open(partial, "wb") as file:
                announced = response.headers.get("Content-Length")
                for chunk in iter(lambda: response.read(_CHUNK), b""):
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
        got = _digest(partial, expected)
        if got != expected:
            raise TeacherDownloadError(
                f"{target.name}: {_checksum_name(expected)} mismatch for {url}: expected {expected}, got {got}; "
                f"nothing was written."
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
    """Downloads the SAIL authors' teacher ``.npz`` files (pinned commit, checked checksum).

    Each file is fetched from ``base_url + name`` (by default the raw URL of
    ``illidanlab/SAIL`` at :data:`PAPER_TEACHERS_COMMIT`, folder ``teacher_dataset/``),
    streamed to a temporary file in ``dest`` and renamed into place only if its checksum is the
    pinned one of :data:`PAPER_TEACHERS` or :data:`OTHER_TEACHERS`: a failed or corrupt download
    leaves no file (and an existing one untouched). A file already in ``dest`` with the right
    checksum is not downloaded again; one with another is replaced.

    Args:
        dest: the folder to put them in, created if needed. Defaults to
            :func:`paper_teachers_dir` (``$TORCHRL_SAIL_TEACHERS``, else the user cache).
        names: file names or ``fnmatch`` patterns (``"*Hopper*"``). Defaults to all 20 published files.

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
    paths, pins = [], _published()
    for name in selected:
        target, expected = folder / name, pins[name]
        checksum = _checksum_name(expected)
        if target.is_file() and _digest(target, expected) == expected:
            logger.info("%s: already in %s (%s ok)", name, folder, checksum)
        else:
            if target.exists():
                logger.warning("%s: %s has another %s; downloading it again", name, target, checksum)
            url = base_url + urllib.parse.quote(name)
            logger.info("%s: downloading %s", name, url)
            _download(url, target, expected, timeout)
            logger.info("%s: written to %s (%s ok)", name, target, checksum)
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
        description="Download the SAIL authors' teacher demonstrations (illidanlab/SAIL at commit "
        f"{PAPER_TEACHERS_COMMIT[:12]}), checking each file's pinned checksum.",
    )
    parser.add_argument("names", nargs="*", help="file names or patterns, e.g. '*Hopper*' (default: all)")
    parser.add_argument("--dest", help=f"folder (default: ${_ENV_VAR}, else ~/.cache/torchrl_sail/teachers)")
    parser.add_argument("--base-url", default=PAPER_TEACHERS_URL, help="where to download from (a mirror)")
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds per request (default: 60)")
    parser.add_argument(
        "--list", action="store_true", help="list the files, the env each loads into, and whether they are in --dest"
    )
    args = parser.parse_args(argv)
    folder = paper_teachers_dir() if args.dest is None else Path(args.dest).expanduser()
    try:
        names = _select(args.names or None)
        if args.list:
            missing = set(missing_paper_teachers(folder, names))
            for name in names:
                env, note = teacher_env(name) or (None, "")
                note = f"refused on loading: {refused_teacher(name)}" if refused_teacher(name) else note
                print(
                    f"{'missing' if name in missing else 'ok     '}  {name}"
                    + (f"  env={env}" if env else "")
                    + (f"  ({note})" if note else "")
                )
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
