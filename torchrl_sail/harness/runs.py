"""The run folder of a training script, and its life cycle: start, resume, log, summarise.

A run folder (the example scripts' ``hydra.run.dir``) holds:

- ``config.yaml``: the resolved config the run (last) went on with;
- ``checkpoint/``: a TorchRL :class:`~torchrl.checkpoint.Checkpoint` (``manifest.json`` and
  one entry per component), among them ``run``, the dict of :func:`new_run`: frames,
  gradient steps, evaluations, logger states and the run's identity;
- ``logs/scalars/<tag>.csv``: TorchRL's ``CSVLogger`` rows ``frames,value``, one file per tag
  (``eval/return`` is ``logs/scalars/eval/return.csv``);
- ``best_policy.pt``: the policy the run kept as its best by its own training returns (the
  SAIL authors' rule, written by the scripts at each checkpoint), and ``best_evaluated_policy.pt``,
  the policy at its best periodic evaluation;
- ``summary.json`` (:func:`write_summary`) and ``learning_curve.png``
  (:func:`plot_learning_curve`), written when the run has done its budget.

A results copy (``benchmarks/campaign.py --collect``) keeps ``config.yaml``, ``summary.json``
and one ``scalars.csv`` (header ``tag,frames,value``) instead of ``logs/``; :func:`read_scalar`
reads both.

The life cycle, as the example scripts run it::

    resuming = resume_mode(run_dir, cfg.resume, cfg.collector.total_frames)  # True, False, or None: skip
    run = new_run(env=..., algo=..., seed=..., teacher=...)
    checkpoint = Checkpoint(run=run, ...)                    # every component a stopped run needs
    start_or_resume(checkpoint, run_dir, run, resuming, config=cfg)
    ...  # train; run["frames"] etc. updated; checkpoint.save(checkpoint_dir(run_dir))
    write_summary(run_dir, {...})
"""

from __future__ import annotations

import csv
import json
import os
import shutil
from collections.abc import Iterable, Mapping
from pathlib import Path

import torch

from torchrl_sail.harness.machine import provenance

#: The names of a run folder's entries.
CONFIG = "config.yaml"
CHECKPOINT = "checkpoint"
BEST_POLICY = "best_policy.pt"
BEST_EVALUATED_POLICY = "best_evaluated_policy.pt"
SUMMARY = "summary.json"
LEARNING_CURVE = "learning_curve.png"
SCALARS = Path("logs") / "scalars"
COLLECTED_SCALARS = "scalars.csv"

# The run's identity entries and the config keys they come from (named in resume errors).
_IDENTITY_KEYS = {"env": "env", "algo": "algo", "seed": "seed", "teacher": "teacher.path"}

#: The config keys a resumed run may change (each with the keys below it): its length,
#: logging, evaluation, checkpoints, hardware and learning rates (a diverged run goes on with a
#: lower one). Any other change would make one curve of two configs, or not fit the checkpoint:
#: ``eval.average_frames`` (the averaged actor the checkpoint holds, and its memory) among them.
RESUME_MAY_CHANGE = (
    "resume",
    "collector.total_frames",
    "collector.num_workers",
    "collector.backend",
    "collector.backend_options",
    "collector.weight_sync_timeout_s",
    "logger",
    "eval.every_frames",
    "eval.episodes",
    "eval.vectorized",
    "eval.actor",
    "eval.other_actor",
    "eval.best_policy",
    "eval.video_every_frames",
    "eval.video_format",
    "eval.video_size",
    "checkpoint",
    "threads",
    "flush_denormal",
    "device",
    "optim.implementation",
    "optim.cudagraphs",
    "optim.lr",
    "optim.actor_lr",
    "optim.discriminator.lr",
    "optim.actor_max_grad_norm",
    "algo.ppo.lr",
    "algo.sac.alpha_lr",
    "algo.rnd.lr",
    "algo.bc.lr",
)


def checkpoint_dir(run_dir: Path) -> Path:
    """``<run_dir>/checkpoint``."""
    return Path(run_dir) / CHECKPOINT


def is_finished(summary: dict, total_frames: int) -> bool:
    """Whether a run's ``summary.json`` shows its budget done: offline runs always, others at
    ``total_frames`` frames or more.

    Examples:
        >>> is_finished({"frames": 3000}, 3000), is_finished({"frames": 2000}, 3000)
        (True, False)
        >>> is_finished({"offline": True}, 3000)
        True
    """
    return bool(summary.get("offline")) or summary.get("frames", 0) >= total_frames


def resume_mode(
    run_dir: Path,
    resume: bool | str,
    total_frames: int,
    *,
    config=None,
    may_change: Iterable[str] = RESUME_MAY_CHANGE,
) -> bool | None:
    """Whether this run continues the one in ``run_dir``: ``True``, ``False``, or ``None`` to skip it.

    ``resume=False`` refuses a folder that holds a checkpoint or logs (a run is never
    overwritten, and TorchRL's CSV logger would append to the old rows), ``resume=True`` needs a
    checkpoint (:func:`restore_run` says so). ``resume="auto"`` (for matrices that must survive
    interruption) skips a run whose ``summary.json`` shows its budget done (:func:`is_finished`),
    continues one with a checkpoint, and starts the rest afresh, first removing the logs of a run
    that stopped before its first checkpoint (nothing can continue them). A finished run is
    skipped only if it was trained with ``config`` (an OmegaConf config or a plain dict; its
    ``config.yaml`` may differ from it in ``may_change`` keys only): a matrix rerun with another
    setting into the same folders must not report the old results as the new ones.

    Args:
        run_dir (Path): the run folder.
        resume (bool or "auto"): the script's ``resume=`` setting.
        total_frames (int): the run's budget (``collector.total_frames``).
        config (optional): this run's config, compared with a finished run's ``config.yaml``.
        may_change (iterable of str): the keys that may differ (:data:`RESUME_MAY_CHANGE`).

    Raises:
        FileExistsError: ``resume=False`` on a folder with a checkpoint or logs.
        FileNotFoundError: ``resume="auto"`` asked for more frames than a finished run without a
            checkpoint holds.
        ValueError: ``resume="auto"`` on a finished run trained with another config (each
            differing key named with both values).
    """
    run_dir = Path(run_dir)
    checkpoint, summary = checkpoint_dir(run_dir), run_dir / SUMMARY
    if resume == "auto":
        if summary.exists():
            done = json.loads(summary.read_text())
            if is_finished(done, total_frames):
                _refuse_other_config(run_dir, config, may_change)
                return None
            if not checkpoint.exists():
                raise FileNotFoundError(
                    f"{run_dir} holds a finished {done.get('frames')}-frame run but no checkpoint to extend it to "
                    f"collector.total_frames={total_frames}; choose another folder."
                )
        if checkpoint.exists():
            return True
        shutil.rmtree(run_dir / "logs", ignore_errors=True)
        return False
    if checkpoint.exists() and not resume:
        raise FileExistsError(
            f"{run_dir} already holds a run (checkpoint/). Continue it with resume=true "
            f"(or resume=auto), or choose another folder with hydra.run.dir=..."
        )
    if (run_dir / "logs").exists() and not resume:
        raise FileExistsError(
            f"{run_dir} holds the logs of a run that stopped before its first checkpoint (logs/, no "
            f"checkpoint/). Start it afresh with resume=auto (which removes them), or choose another "
            f"folder with hydra.run.dir=..."
        )
    return resume


def _refuse_other_config(run_dir: Path, config, may_change: Iterable[str]) -> None:
    """Raises if the finished run in ``run_dir`` was trained with another config than ``config``."""
    if config is None or not (run_dir / CONFIG).exists():
        return
    from omegaconf import DictConfig, OmegaConf

    if isinstance(config, DictConfig):
        config = OmegaConf.to_container(config, resolve=True, enum_to_str=True)
    saved = OmegaConf.to_container(OmegaConf.load(run_dir / CONFIG))
    changes = config_changes(saved, config)
    refused = [f"{k}={o!r} (this run: {n!r})" for k, (o, n) in changes.items() if not _may_change(k, may_change)]
    if refused:
        raise ValueError(
            f"resume=auto: {run_dir} holds a finished run trained with " + ", ".join(refused) + "; it would "
            "be skipped and its results taken for this config. Use the same settings, or another hydra.run.dir."
        )


#: The config's open mappings, whose entries are the user's (``+env.kwargs.<name>=...``), not a
#: version's settings: compared as whole values, so that adding or removing an entry is a change.
OPEN_MAPPINGS = ("env.kwargs",)


def config_changes(saved: Mapping, current: Mapping, *, whole: Iterable[str] = OPEN_MAPPINGS) -> dict[str, tuple]:
    """The dotted keys whose values differ between two plain nested configs, with ``(saved, current)``.

    Keys that only one of them has are not compared (a config written by another version; see
    :func:`config_additions`), except inside the mappings ``whole`` names, which are compared as
    whole values.

    Examples:
        >>> config_changes({"seed": 0, "optim": {"lr": 1e-3, "tau": 0.005}, "old": 1},
        ...                {"seed": 0, "optim": {"lr": 1e-4, "tau": 0.005}, "new": 2})
        {'optim.lr': (0.001, 0.0001)}
        >>> config_changes({"env": {"kwargs": {}}}, {"env": {"kwargs": {"ctrl_cost_weight": 5.0}}})
        {'env.kwargs': ({}, {'ctrl_cost_weight': 5.0})}
    """
    return dict(sorted(_changes(saved, current, set(whole), "").items()))


def _changes(saved: Mapping, current: Mapping, whole: set[str], prefix: str) -> dict[str, tuple]:
    changes = {}
    for key in saved.keys() & current.keys():
        name, old, new = f"{prefix}{key}", saved[key], current[key]
        if isinstance(old, Mapping) and isinstance(new, Mapping) and name not in whole:
            changes.update(_changes(old, new, whole, f"{name}."))
        elif old != new:
            changes[name] = (old, new)
    return changes


def config_additions(saved: Mapping, current: Mapping, *, whole: Iterable[str] = OPEN_MAPPINGS) -> dict:
    """The dotted keys ``current`` has and ``saved`` lacks, with their ``current`` values: settings a
    newer version added, which a run resumed from an older version's checkpoint takes at their
    current values. The entries of the mappings ``whole`` names are :func:`config_changes`' instead.

    Examples:
        >>> config_additions({"seed": 0, "optim": {"lr": 1e-3}},
        ...                  {"seed": 0, "optim": {"lr": 1e-3, "coef": 0.1}, "new": 2})
        {'new': 2, 'optim.coef': 0.1}
    """
    return dict(sorted(_additions(saved, current, set(whole), "").items()))


def _additions(saved: Mapping, current: Mapping, whole: set[str], prefix: str) -> dict:
    added = {}
    for key, new in current.items():
        name = f"{prefix}{key}"
        if key not in saved:
            added[name] = new
        elif isinstance(saved[key], Mapping) and isinstance(new, Mapping) and name not in whole:
            added.update(_additions(saved[key], new, whole, f"{name}."))
    return added


def _may_change(key: str, allowed: Iterable[str]) -> bool:
    """Whether the dotted ``key`` is one of ``allowed`` or below one (``eval`` covers ``eval.episodes``)."""
    return any(key == a or key.startswith(a + ".") for a in allowed)


def new_run(*, env: str, algo: str, seed: int, teacher: str | None) -> dict:
    """The run's own state, saved with the checkpoint as its ``run`` component.

    Counters (``frames``, ``gradient_steps``), the evaluations ``evals`` (``[frames, mean return]``
    pairs, see :func:`add_evaluation`) and ``passed_teacher_at``, the non-CSV loggers' states
    (``loggers``), the ``identity`` a resumed run must match, the resolved ``config`` it trains
    with (set by :func:`start_or_resume`), ``resumes``: the config changes each resume made
    (``{"frames": ..., "changes": {key: [saved, new]}}``, and ``"added"`` and ``"removed"`` where any, see
    :func:`restore_run`), and
    ``wall_seconds``: the wall time of its training loop over all its starts, each up to its last
    checkpoint (building and imports left out; ``None`` for a run continued from a checkpoint of
    an earlier version, which did not keep it; the scripts update it with :func:`wall_time` at
    each save), and ``starts``: the :func:`provenance` of every start of the run, each with the
    frame it started from (:func:`start_or_resume` appends it).

    Examples:
        >>> new_run(env="Hopper-v4", algo="sail", seed=0, teacher=None)["identity"]
        {'env': 'Hopper-v4', 'algo': 'sail', 'seed': 0, 'teacher': None}
    """
    return {
        "frames": 0,
        "gradient_steps": 0,
        "evals": [],
        "passed_teacher_at": None,
        "loggers": {},
        "identity": {"env": env, "algo": algo, "seed": seed, "teacher": teacher},
        "config": None,
        "resumes": [],
        "wall_seconds": 0.0,
        "starts": [],
    }


def wall_time(base: float | None, since: float, now: float) -> float | None:
    """A run's wall time in all: ``base``, its ``wall_seconds`` when this start began (``None``:
    unknown), plus this start's ``now - since``.

    Examples:
        >>> wall_time(100.0, since=5.0, now=35.0), wall_time(None, since=5.0, now=35.0)
        (130.0, None)
    """
    return None if base is None else base + (now - since)


def add_evaluation(run: dict, frames: int, value: float, teacher_return: float) -> None:
    """Records an evaluation's mean return at ``frames`` in ``run["evals"]``, and the first frame it
    beat the teacher in ``run["passed_teacher_at"]``.

    Examples:
        >>> run = new_run(env="Hopper-v4", algo="sail", seed=0, teacher=None)
        >>> for frames, value in [(1000, 5.0), (2000, 30.0), (3000, 12.0)]:
        ...     add_evaluation(run, frames, value, teacher_return=20.0)
        >>> run["evals"], run["passed_teacher_at"]
        ([(1000, 5.0), (2000, 30.0), (3000, 12.0)], 2000)
    """
    run["evals"].append((frames, value))
    if run["passed_teacher_at"] is None and value > teacher_return:
        run["passed_teacher_at"] = frames


def fall_share(evals: Iterable[tuple[int, float]], teacher_return: float) -> dict | None:
    """How often a run's evaluations fell below its teacher after it first passed it.

    Counts the evaluations after the first one above ``teacher_return`` (that one excluded) and
    those of them below ``teacher_return``. ``None`` for a run that never passed its teacher.

    Returns:
        ``{"share": falls / evaluations (None without any), "falls": ..., "evaluations": ...}``

    Examples:
        >>> fall_share([(1000, 5.0), (2000, 30.0), (3000, 12.0), (4000, 31.0)], teacher_return=20.0)
        {'share': 0.5, 'falls': 1, 'evaluations': 2}
        >>> fall_share([(1000, 5.0)], teacher_return=20.0) is None
        True
    """
    values = [value for _, value in sorted(evals, key=lambda pair: pair[0])]  # (a resumed run's pairs are lists)
    first = next((i for i, value in enumerate(values) if value > teacher_return), None)
    if first is None:
        return None
    after = values[first + 1 :]
    falls = sum(value < teacher_return for value in after)
    return {"share": falls / len(after) if after else None, "falls": falls, "evaluations": len(after)}


def start_or_resume(
    checkpoint,
    run_dir: Path,
    run: dict,
    resuming: bool,
    *,
    optimizers: Iterable = (),
    truncate_logs: bool = True,
    config=None,
    may_change: Iterable[str] = RESUME_MAY_CHANGE,
    may_start_empty: Iterable[str] = (),
    code_dir: Path | None = None,
) -> None:
    """Restores ``checkpoint`` from ``run_dir`` when ``resuming`` (:func:`restore_run`), appends this
    start's :func:`provenance` (of ``code_dir``) to ``run["starts"]``, then writes ``config`` (an
    OmegaConf config) to ``config.yaml``, resolved: the config the run goes on with.

    ``config`` is also kept in ``run["config"]`` (without its ``resume`` entry), so each
    checkpoint holds the config it was trained with, and a resume is checked against it
    (:func:`restore_run`). Only a resume that
    passed its checks drops the run's old ``summary.json`` (a continued run is unfinished until
    it ends). The ``optimizers`` keep the settings they were built with from the config (learning
    rate, ``capturable``, ``fused``, ...; the saved state holds the old ones): a run continued with
    another learning rate (e.g. after a divergence), or with CUDA graphs, uses them.
    """
    run_dir = Path(run_dir)
    current = None
    if config is not None:
        from omegaconf import OmegaConf

        current = OmegaConf.to_container(config, resolve=True, enum_to_str=True)
        current.pop("resume", None)  # how this process started, not how the run trains
    if resuming:
        optimizers = list(optimizers)
        configured = [[_settings(group) for group in optimizer.param_groups] for optimizer in optimizers]
        restore_run(
            checkpoint,
            run_dir,
            run,
            truncate_logs=truncate_logs,
            config=current,
            may_change=may_change,
            may_start_empty=may_start_empty,
        )
        for optimizer, settings in zip(optimizers, configured, strict=True):
            for group, setting in zip(optimizer.param_groups, settings, strict=True):
                group.update(setting)
            _place_steps(optimizer)
        if truncate_logs:
            (run_dir / SUMMARY).unlink(missing_ok=True)
    # every start's code and machine, not only the last one's: a resumed run may span commits
    run.setdefault("starts", []).append({"frames": run["frames"], **provenance(code_dir)})
    if config is not None:
        run["config"] = current
        OmegaConf.save(config, run_dir / CONFIG, resolve=True)


def _settings(group: dict) -> dict:
    """An optimizer param group's settings (everything but its parameters)."""
    return {key: value for key, value in group.items() if key != "params"}


def _place_steps(optimizer) -> None:
    """Puts each tensor ``step`` in the state where the group's settings want it, as torch's own
    ``load_state_dict`` does for the saved settings: on the parameter's device in float32 for
    ``capturable`` or ``fused`` groups, on the CPU otherwise."""
    for group in optimizer.param_groups:
        on_device = group.get("capturable", False) or group.get("fused", False)
        for param in group["params"]:
            step = optimizer.state.get(param, {}).get("step")
            if torch.is_tensor(step):
                device = param.device if on_device else torch.device("cpu")
                dtype = torch.float32 if on_device else step.dtype
                optimizer.state[param]["step"] = step.to(device=device, dtype=dtype)


def restore_run(
    checkpoint,
    run_dir: Path,
    run: dict,
    *,
    truncate_logs: bool = True,
    config: Mapping | None = None,
    may_change: Iterable[str] = RESUME_MAY_CHANGE,
    may_start_empty: Iterable[str] = (),
) -> None:
    """Restores every component of ``checkpoint`` from ``<run_dir>/checkpoint``, after checking it is this run's.

    ``run`` is the :func:`new_run` dict of this run (a component of ``checkpoint``): its
    ``identity`` is compared with the saved one first (a checkpoint saved without the
    ``teacher`` entry is not checked on it). Then ``config`` (this run's resolved config, a
    plain dict) is compared with the one the checkpoint was trained with (``run["config"]``,
    or ``config.yaml`` for a checkpoint that has none): a change of a key outside
    ``may_change`` (:data:`RESUME_MAY_CHANGE`) is refused, before anything else is loaded; the
    allowed changes are printed and appended to ``run["resumes"]`` with the frame they apply
    from, and so are the keys ``config`` has and the checkpoint's lacks (``"added"``: settings of a
    newer version, at this run's values; :func:`config_additions`) and those it lacks and the
    checkpoint's has (``"removed"``, at their saved values). ``truncate_logs`` then drops
    the CSV rows logged after the checkpoint's frame (:func:`truncate_scalar_logs`: this run logs
    them again); offline runs, whose logs are not indexed by frames, keep theirs. A component of
    ``may_start_empty`` (state a newer version keeps, e.g. ``best_evaluated_policy``) that the
    checkpoint lacks keeps its fresh state from the checkpoint's frame on, also recorded in
    ``run["resumes"]`` (``"started_empty"``).

    Raises:
        FileNotFoundError: no ``manifest.json`` in the checkpoint folder.
        ValueError: an unreadable checkpoint, one written by another env, algo, seed or teacher,
            a config change outside ``may_change`` (each such key named with its saved and
            its new value), a checkpoint holding components ``checkpoint`` lacks, or lacking
            components ``checkpoint`` has, outside ``may_start_empty`` (named).
    """
    path = checkpoint_dir(run_dir)
    if not (path / "manifest.json").exists():
        raise FileNotFoundError(
            f"resume=true but there is no checkpoint at {path}: start without resume=true, or point "
            f"hydra.run.dir at the run folder to continue."
        )
    this = dict(run["identity"])
    try:
        checkpoint.load(path, components=["run"])
    except Exception as err:  # a damaged folder, or one this version cannot read
        raise ValueError(
            f"checkpoint {path} is unreadable ({type(err).__name__}: {err}). If it is damaged (an interrupted "
            f"save, a full disk), move it away to start the run over; if it was written by another version of "
            f"torchrl_sail or TorchRL, resume with that version."
        ) from err
    for key, saved in run["identity"].items():
        if saved != this[key]:
            name = _IDENTITY_KEYS.get(key, key)
            raise ValueError(
                f"resume: {path} was written with {name}={saved!r}, "
                f"this run has {name}={this[key]!r}; use the same value."
            )
    trained = None if config is None else _trained_config(run, run_dir)
    changes = {} if config is None else _config_changes_on_resume(path, trained, config, may_change)
    # settings another version added (at this run's values from here) or removed (the saved values)
    added = {} if trained is None else {k: v for k, v in config_additions(trained, config).items() if k != "resume"}
    removed = {} if trained is None else {k: v for k, v in config_additions(config, trained).items() if k != "resume"}
    # TorchRL's Checkpoint skips saved components it was not given: their state would be lost for good
    saved = set(checkpoint.manifest(path)["components"])
    dropped = sorted(saved.difference(checkpoint.components))
    if dropped:
        raise ValueError(
            f"resume: {path} holds {dropped}, which this run does not keep: it was trained with settings that "
            f"need them (e.g. algo.sac.fixed_alpha=false for a learned temperature's optimizer); resume with those."
        )
    lacking = sorted(set(checkpoint.components).difference(saved))
    if set(lacking).difference(may_start_empty):
        raise ValueError(
            f"resume: {path} lacks {sorted(set(lacking).difference(may_start_empty))}, which this run keeps: it "
            f"was written with other settings or by another version; resume with those."
        )
    checkpoint.load(path, components=sorted(saved))
    run.setdefault("resumes", [])  # a checkpoint of an earlier version has none
    run.setdefault("wall_seconds", None)  # nor its wall time: unknown
    frames = run["frames"]
    if changes:
        print(f"resume at frame {frames}: " + ", ".join(f"{k}={o!r} -> {n!r}" for k, (o, n) in changes.items()))
    for what, keys in (("lacks", added), ("has, this version does not,", removed)):
        if keys:
            listed = ", ".join(f"{k}={v!r}" for k, v in keys.items())
            print(f"resume at frame {frames}: the checkpoint's config {what} {listed} (another version's settings)")
    if lacking:
        print(f"resume at frame {frames}: the checkpoint has no {lacking} (another version's); they start from here")
    if changes or added or removed or lacking:
        resume = {"frames": frames, "changes": {k: [o, n] for k, (o, n) in changes.items()}}
        resume.update({name: keys for name, keys in (("added", added), ("removed", removed)) if keys})
        resume.update({"started_empty": lacking} if lacking else {})
        run["resumes"].append(resume)
    if truncate_logs:
        truncate_scalar_logs(run_dir, run["frames"])


def _trained_config(run: dict, run_dir: Path) -> Mapping | None:
    """The config a loaded ``run`` was trained with: its own, else ``config.yaml`` (else ``None``)."""
    if run.get("config") is not None:
        return run["config"]
    if (Path(run_dir) / CONFIG).exists():
        from omegaconf import OmegaConf

        return OmegaConf.to_container(OmegaConf.load(Path(run_dir) / CONFIG))
    return None


def _config_changes_on_resume(path: Path, saved, config: Mapping, may_change: Iterable[str]) -> dict[str, tuple]:
    """The allowed config changes of a resume (``resume`` itself left out); raises on any other."""
    changes = {} if saved is None else config_changes(saved, config)
    refused = [f"{k}={o!r}, this run has {k}={n!r}" for k, (o, n) in changes.items() if not _may_change(k, may_change)]
    if refused:
        raise ValueError(
            f"resume: {path} was written with "
            + "; with ".join(refused)
            + ". A resumed run may change only its length, logging, evaluation, checkpoints, hardware and "
            "learning rates: use the saved values, or start a new run in another hydra.run.dir."
        )
    return {k: v for k, v in changes.items() if k != "resume"}


def truncate_scalar_logs(run_dir: Path, frames: int) -> list[Path]:
    """Drops the rows logged after ``frames`` from every CSV of ``<run_dir>/logs/scalars``, and the
    rows a crash left damaged (unparsable, or a last line without its newline: the resumed run's
    next row would be glued to it); returns the files it rewrote (each atomically).

    Examples:
        >>> import tempfile
        >>> run_dir = Path(tempfile.mkdtemp())
        >>> log = run_dir / "logs" / "scalars" / "eval" / "return.csv"
        >>> log.parent.mkdir(parents=True)
        >>> _ = log.write_text("1000,5.0\\n2000,7.5\\n3000,9.0\\n4000,1")  # killed mid-row at 4000
        >>> _ = truncate_scalar_logs(run_dir, 2000)
        >>> log.read_text()
        '1000,5.0\\n2000,7.5\\n'
    """
    truncated = []
    for path in sorted((Path(run_dir) / SCALARS).glob("**/*.csv")):
        lines = path.read_text(errors="replace").splitlines(keepends=True)
        kept = [line for line in lines if line.endswith("\n") and _logged_at(line) <= frames]
        if len(kept) != len(lines):
            write_atomic(path, "".join(kept))
            truncated.append(path)
    return truncated


def _logged_at(line: str) -> float:
    """A CSV row's frame (its first field); infinity for a damaged row, which no frame keeps."""
    try:
        return float(line.split(",", 1)[0])
    except ValueError:
        return float("inf")


def checkpoint_frames(run_dir: Path) -> int | None:
    """The frame of the run's last saved checkpoint, read from its ``run`` component without loading
    the checkpoint; ``None`` when none is saved.

    Raises:
        ValueError: a checkpoint whose manifest or ``run`` component cannot be read, naming the file.

    Examples:
        >>> import json, tempfile
        >>> run_dir = Path(tempfile.mkdtemp())
        >>> checkpoint_frames(run_dir) is None
        True
        >>> (run_dir / "checkpoint" / "components" / "0009-run").mkdir(parents=True)
        >>> _ = (run_dir / "checkpoint" / "manifest.json").write_text(
        ...     json.dumps({"components": {"run": {"path": "components/0009-run", "files": ["value.json"]}}}))
        >>> _ = (run_dir / "checkpoint" / "components" / "0009-run" / "value.json").write_text('{"frames": 25000}')
        >>> checkpoint_frames(run_dir)
        25000
    """
    manifest = checkpoint_dir(run_dir) / "manifest.json"
    if not manifest.exists():
        return None
    try:
        value = checkpoint_dir(run_dir) / json.loads(manifest.read_text())["components"]["run"]["path"] / "value.json"
        return int(json.loads(value.read_text())["frames"])
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ValueError(f"{manifest}: no readable run component ({type(err).__name__}: {err})") from err


def last_checkpoint(run_dir: Path, run: dict) -> str | None:
    """``"<run_dir>/checkpoint, frame <n>"`` once a checkpoint is saved (for error messages), else ``None``."""
    path = checkpoint_dir(run_dir)
    return f"{path}, frame {run['frames']}" if (path / "manifest.json").exists() else None


#: Both accuracies at or above this: the discriminator tells every row's side (saturated).
def read_scalar(run_dir: Path, tag: str) -> list[tuple[int, float]]:
    """The ``(frames, value)`` rows of one logged scalar, as logged (file order, every row).

    Reads ``<run_dir>/logs/scalars/<tag>.csv`` (TorchRL's ``CSVLogger``), or, in a results copy
    holding ``scalars.csv`` (``tag,frames,value``), the rows of ``tag`` there. A tag never
    logged gives ``[]``.

    Raises:
        ValueError: a row that is not ``frames,value``, naming the file and line.

    Examples:
        >>> import tempfile
        >>> run_dir = Path(tempfile.mkdtemp())
        >>> (run_dir / "logs" / "scalars" / "eval").mkdir(parents=True)
        >>> _ = (run_dir / "logs" / "scalars" / "eval" / "return.csv").write_text("1000,12.5\\n2000,30.0\\n")
        >>> read_scalar(run_dir, "eval/return"), read_scalar(run_dir, "alpha")
        ([(1000, 12.5), (2000, 30.0)], [])
    """
    run_dir = Path(run_dir)
    collected = run_dir / COLLECTED_SCALARS
    if collected.exists():
        with open(collected, newline="") as file:
            rows = [
                (line, row["frames"], row["value"])
                for line, row in enumerate(csv.DictReader(file), 2)
                if row["tag"] == tag
            ]
        return [_scalar_row(collected, line, frames, value) for line, frames, value in rows]
    path = run_dir / SCALARS / f"{tag}.csv"
    if not path.exists():
        return []
    out = []
    for line, text in enumerate(path.read_text().splitlines(), 1):
        if text.strip():
            fields = text.split(",")
            out.append(_scalar_row(path, line, *fields) if len(fields) == 2 else _bad_row(path, line, text))
    return out


def _scalar_row(path: Path, line: int, frames, value) -> tuple[int, float]:
    try:
        return int(float(frames)), float(value)
    except (TypeError, ValueError):
        _bad_row(path, line, f"{frames},{value}")


def _bad_row(path: Path, line: int, text: str):
    raise ValueError(f"{path}, line {line}: expected 'frames,value', got {text!r}")


def write_atomic(path: Path, text: str) -> None:
    """Writes ``path`` so that a crash never leaves it half-written (a temporary file, then a rename)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
