"""Aggregates the training scripts' run folders into the paper's results table and learning curves.

    python benchmarks/aggregate.py benchmarks/runs/hopper50k --out benchmarks/runs/hopper50k/report \
        [--expect-methods sail td3_delayed] [--expect-seeds 0 1 2] [--per-run] [--write-into FILE:BLOCK]
    python benchmarks/aggregate.py --update-docs   # every generated block and file, from benchmarks/results/

A run folder is any folder holding ``config.yaml`` (hidden folders such as Hydra's ``.hydra/``
are skipped). Runs are grouped by (env, teacher, method): the teacher is the folder name under a
``run_matrix.py`` folder (the nearest ``matrix.json`` above the run), else the teacher file's
name (``shipped`` for the env's default teacher). Writes to ``--out``:

- ``results.md`` and ``results.csv``: one row per group, from each run's deterministic
  evaluations (``logs/scalars/eval/return.csv``: frames, mean return of ``eval.episodes``
  episodes; the reporting spec asks for 10 episodes, and other counts are noted). Per run:

  - the headline figure: the mean of its last 5 evaluations (``HEADLINE_EVALS``; of all its
    evaluations when it has fewer, marked † in the table and named in the notes);
  - final: its last evaluation; best: its highest evaluation;
  - frames to pass the teacher: the frames at its first evaluation whose return is above the
    teacher's (``summary.json``'s ``passed_teacher_at_frame``, else from the curve; None if never);
  - fall share: of its evaluations after the first one above the teacher's return (that one
    excluded), those below it (``torchrl_sail.harness.fall_share`` of the eval curve; None if it
    never passed);
  - best policy: ``summary.json``'s ``best_policy.eval_return``, the evaluation of the policy it
    kept by its own training returns (absent in runs that did not evaluate one, older runs);
  - best evaluated policy: ``summary.json``'s ``best_evaluated_policy.eval_return``, the policy at its
    best periodic evaluation, evaluated on other episodes (absent in older runs).

  Per group, over seeds: the headline mean (the first column after env, teacher and method:
  "last-5 mean", ``last5_mean`` in the CSV), its sample std (ddof=1) and 95% Student-t CI
  of the mean (both n/a for one seed), the best policy's mean and std over the seeds that have
  it ("best policy" beside the headline, ``best_policy_mean``, ``best_policy_std`` and
  ``best_policy_n`` in the CSV; ``-`` if none has it, "k/n seeds" and a note if only some do),
  the same of the best evaluated policy (``best_evaluated_mean``, ``_std`` and ``_n``, in the CSV only),
  the mean final and mean best evaluation, headline mean / teacher return (the median of the
  seeds' teacher returns), the frames to pass the teacher (median over the seeds that passed,
  with "k/n seeds passed"), and the fall share pooled over the seeds that passed: their falls
  over their evaluations after passing, ``18.6% (13/70)`` (``fall_share`` as a fraction,
  ``falls`` and ``fall_evaluations`` in the CSV; n/a if no seed passed), so that a seed that
  passed late, with few evaluations left, weighs by those few.
  A run without an eval CSV (``logger.backends`` without csv) counts ``summary.json``'s final
  evaluation as its one evaluation (and its ``best_eval_return`` as best), noted as such;
- ``curves_<env>_<teacher>.png``: eval return against frames, one colour per method (mean over
  seeds, min-max band), the teacher's return dashed, offline methods (one evaluation each, at
  their headline mean) as dotted lines.

A teacher label ``<base>-<variant>`` whose ``<base>`` is another label (the campaign's buffer,
precision and remedy stages: ``paper-fifo``, ``random-preact``) is also set beside its base in a
"Variants beside their base" section of ``results.md``: the variant's headline, vs teacher and fall
share and the base's, for the same env, method and budget, and Welch's t-test of the two sets of
seeds' headlines.

Runs of one (env, teacher, method) at different budgets (``collector.total_frames``, e.g. the
campaign's 300k and 1M SAIL runs) are different cells: their method is shown with the budget,
``sail (1M)``.

Generated blocks. ``--write-into FILE:BLOCK`` also writes the block ``BLOCK`` (a name of
:data:`BLOCKS`), made from these runs, into the Markdown file ``FILE``, between the lines
``<!-- aggregate:BLOCK START -->`` and ``<!-- aggregate:BLOCK END -->``: e.g. ``campaign-readme``, the
README's results section for the runs of one teacher (``--teacher``, default ``paper``) in the
paper's Table 1 format (methods by env, the headline mean ± std over seeds, under SAIL and DAC their
best policy and fall share, the teacher's return and the paper's SAIL beside them), with
``results_<teacher>.png`` (one panel per env), the budget, the CPUs, the wall time and the command of
every cell (with the settings its runs had that differ from what the method composes now);
``--default-label`` names the teacher label of the default SAIL's runs where it is another (the
campaign's ``TABLE1_LABEL``, which ``--update-docs`` reads): their rows are ``sail``'s, and the
teacher's own SAIL rows the replaced default's; ``paper-comparison``, the paper's comparison in its
layout (Table 1's SAIL and exploration variants beside the paper's figures, Figure 2's baselines,
Figures 3-4's variants of SAIL, with ``paper_figure2_<teacher>.png`` and ``paper_figures34_<teacher>.png``
of their curves), each cell the last-5 and the best-policy means. ``--update-docs`` writes every block of
:data:`DOCUMENTS` (the README, ``docs/results.md``, the speed tables of ``docs/performance.md``
and the studies' READMEs) and every file of
:func:`generated_files` from the runs committed under ``benchmarks/results/``; ``--check`` writes
nothing and names each block or file that differs from what they would be (exit status 1).

``--per-run`` adds a "Runs" section to ``results.md``: per finished run, its eval curve, when it
first passed the teacher and its fall share since, its best and final evaluation, its best logged
training return, when alpha switched (first promotion), promotions and the final threshold C, its
best policy's evaluation, frames/s and peak memory
(from ``summary.json`` and the logs; ``read_scalar`` reads a live run's ``logs/scalars/`` and a
results copy's ``scalars.csv``).

Only finished runs count. Missing runs (expected by ``--expect-*`` or ``matrix.json`` and
absent), unfinished ones (no ``summary.json``, or fewer frames than ``collector.total_frames``)
and duplicates are listed in a "Missing or unfinished runs" section, never averaged in.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import functools
import importlib
import io
import json
import math
import os
import re
import statistics
import sys
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

# read_scalar: logs/scalars/<tag>.csv or scalars.csv
from torchrl_sail.harness import (
    ACTOR_SATURATED,
    COLLECTED_SCALARS,
    D_SATURATED,
    config_changes,
    fall_share,
    read_scalar,
    write_atomic,
)

BENCHMARKS = Path(__file__).resolve().parent
REPO = BENCHMARKS.parent
# Display order; methods not listed here come after, alphabetically.
METHOD_ORDER = (
    "sail",
    "sail, replaced default",
    "sail_no_lfd",
    "sail_no_adapt",
    "sail_onpolicy",
    "sail_sac",
    "sail_rnd",
    "td3_delayed",
    "dac",
    "ddpgfd",
    "pofd",
    "pofd_td3",
    "gail",
    "bc",
)
# The paper's Table 1: SAIL at 1M frames, mean ± std over 5 seeds (its -v2 envs; ours are -v4).
PAPER_SAIL = {
    "HalfCheetah": (10660.6, 105.5),
    "Swimmer": (309.5, 3.0),
    "Hopper": (3302.1, 14.2),
    "Walker2d": (5868.5, 108.8),
}
PAPER_ENVS = tuple(PAPER_SAIL)  # Table 1's column order
# Table 1's other rows: its two exploration variants (1M frames, 5 seeds) and the teachers' returns
PAPER_TABLE1 = {
    "sail": PAPER_SAIL,
    "sail_rnd": {
        "HalfCheetah": (9043.1, 166.0),
        "Swimmer": (30.9, 6.5),
        "Hopper": (3075.5, 15.6),
        "Walker2d": (5361.8, 58.2),
    },
    "sail_sac": {
        "HalfCheetah": (8839.3, 280.5),
        "Swimmer": (65.0, 7.7),
        "Hopper": (3079.3, 53.3),
        "Walker2d": (2792.8, 830.2),
    },
}
PAPER_TEACHER_RETURNS = {"HalfCheetah": 5646.71, "Swimmer": 121.16, "Hopper": 1480.69, "Walker2d": 1675.01}
# The rows of the paper's comparison, by table: Table 1 (its names), Figure 2's baselines, Figures 3-4's
# variants of SAIL (on-policy D, without LfD, without teacher adaptation), which the paper shows as
# curves only
TABLE1_ROWS = {"sail": "SAIL", "sail_rnd": "Curiosity Exploration", "sail_sac": "Entropy Exploration"}
# (the paper's DAC: the SAIL authors' DAC, `dac`, and Kostrikov et al.'s release, `dac_published`)
FIGURE2_ROWS = ("sail", "dac", "dac_published", "gail", "pofd", "ddpgfd", "bc")
FIGURE34_ROWS = ("sail", "sail_onpolicy", "sail_no_lfd", "sail_no_adapt")
HEADLINE_EVALS = 5  # the headline figure of a run: the mean of its last 5 evaluations
HEADLINE = f"last{HEADLINE_EVALS}"  # its CSV column prefix
SPEC_EVAL_EPISODES = 10  # episodes per evaluation the reporting spec asks for
NA = "n/a"
# Config keys that legitimately differ between the seeds of one group.
PER_RUN_KEYS = ("seed", "resume", "teacher.path", "device", "threads", "flush_denormal", "logger.")
# Settings a resume may change that leave what a run learns and how it is evaluated alone: a
# run's summary records every resume's changes (`resumes`), and the notes name the others.
# Each covers the keys below it (`logger` covers `logger.backends`).
OPERATIONAL_RESUME_KEYS = (
    "collector.total_frames",
    "collector.num_workers",
    "collector.backend",
    "collector.backend_options",
    "collector.weight_sync_timeout_s",
    "threads",
    "flush_denormal",
    "device",
    "optim.implementation",
    "optim.cudagraphs",
    "logger",
    "checkpoint",
)


@dataclass
class Run:
    """One run folder, read."""

    folder: Path
    env: str
    method: str
    seed: int
    teacher: str
    config: dict
    summary: dict | None
    curve: list[tuple[int, float]]  # (frames, deterministic eval return)
    problem: str | None = None  # why the run does not count; None: a finished run

    @property
    def offline(self) -> bool:
        return bool(self.summary and self.summary.get("offline"))

    @property
    def eval_returns(self) -> list[float]:
        """The deterministic eval returns in frame order; without an eval CSV, the summary's final one."""
        if self.curve:
            return [value for _, value in self.curve]
        value = (self.summary or {}).get("final_eval_return")
        return [] if value is None else [float(value)]

    @property
    def headline_evals(self) -> int:
        """How many evaluations the headline averages: ``HEADLINE_EVALS``, or all of them if fewer."""
        return min(HEADLINE_EVALS, len(self.eval_returns))

    @property
    def headline_return(self) -> float | None:
        """The headline figure: the mean of the last ``HEADLINE_EVALS`` eval returns (all, if fewer)."""
        returns = self.eval_returns[-HEADLINE_EVALS:]
        return statistics.fmean(returns) if returns else None

    @property
    def final_return(self) -> float | None:
        """The last eval return."""
        returns = self.eval_returns
        return returns[-1] if returns else None

    @property
    def best_return(self) -> float | None:
        """The highest eval return (without an eval CSV: the summary's ``best_eval_return``, else the final)."""
        if self.curve:
            return max(value for _, value in self.curve)
        value = (self.summary or {}).get("best_eval_return")
        return float(value) if value is not None else self.final_return

    @property
    def eval_episodes(self) -> int | None:
        """Episodes per evaluation (``eval.episodes`` of the config), None where the config lacks it."""
        value = (self.config.get("eval") or {}).get("episodes")
        return None if value is None else int(value)

    @property
    def teacher_return(self) -> float | None:
        value = (self.summary or {}).get("teacher_return")
        return None if value is None else float(value)

    @property
    def fall_share(self) -> dict | None:
        """:func:`~torchrl_sail.harness.fall_share` of its eval curve (the headline's evaluations) and its
        teacher return: None if it never passed the teacher (or has no curve or teacher return)."""
        teacher = self.teacher_return
        return None if teacher is None else fall_share(self.curve, teacher)

    @property
    def best_policy_return(self) -> float | None:
        """``summary.json``'s ``best_policy.eval_return``: the evaluation of the policy it kept by its
        training returns; None for runs that did not evaluate it (older runs have no ``best_policy``)."""
        value = ((self.summary or {}).get("best_policy") or {}).get("eval_return")
        return None if value is None else float(value)

    @property
    def best_evaluated_return(self) -> float | None:
        """``summary.json``'s ``best_evaluated_policy.eval_return``: the evaluation of the policy at its
        best periodic evaluation, on other episodes; None for runs without one (older runs)."""
        value = ((self.summary or {}).get("best_evaluated_policy") or {}).get("eval_return")
        return None if value is None else float(value)

    def passed_teacher_at(self) -> int | None:
        """Frames at the first eval above the teacher's return (the summary's, else from the curve)."""
        if self.summary and "passed_teacher_at_frame" in self.summary:
            return self.summary["passed_teacher_at_frame"]
        teacher = self.teacher_return
        return next((frames for frames, value in self.curve if teacher is not None and value > teacher), None)


@dataclass
class Group:
    """The finished runs of one (env, teacher, method), with their statistics."""

    env: str
    teacher: str
    method: str
    runs: list[Run] = field(default_factory=list)

    @property
    def values(self) -> list[float]:
        """The seeds' headline figures (mean of the last ``HEADLINE_EVALS`` evaluations)."""
        return [run.headline_return for run in self.runs]

    @property
    def teacher_return(self) -> float | None:
        returns = [run.teacher_return for run in self.runs if run.teacher_return is not None]
        return statistics.median(returns) if returns else None

    @property
    def offline(self) -> bool:
        return all(run.offline for run in self.runs)

    def stats(self) -> dict:
        """Over seeds: the headline's mean, sample std (ddof=1) and 95% CI (std and CI None for one
        seed), the best policy's evaluation (mean and std over the ``best_policy_n`` seeds that have
        one), the mean final and best evaluation, headline mean / teacher return, the frames to pass
        the teacher (median over the seeds that passed; ``seeds_past_teacher``: "k/n"), and the fall
        share pooled over the seeds that passed (``falls`` / ``fall_evaluations``; all three None if
        none passed, the share None without evaluations after passing)."""
        values = self.values
        mean = statistics.fmean(values)
        std = statistics.stdev(values) if len(values) > 1 else None
        low, high = t_ci(values)
        passed = [run.passed_teacher_at() for run in self.runs]
        passed = [frames for frames in passed if frames is not None]
        teacher = self.teacher_return
        best_policy = [run.best_policy_return for run in self.runs if run.best_policy_return is not None]
        best_evaluated = [run.best_evaluated_return for run in self.runs if run.best_evaluated_return is not None]
        # pooled, not a mean of per-seed shares: a seed that passed late has few evaluations to weigh
        shares = [share for share in (run.fall_share for run in self.runs) if share is not None]
        falls = sum(share["falls"] for share in shares) if shares else None
        after = sum(share["evaluations"] for share in shares) if shares else None
        return {
            "n_seeds": len(values),
            "seeds": sorted(run.seed for run in self.runs),
            "headline_mean": mean,
            "headline_std": std,
            "ci95_low": low,
            "ci95_high": high,
            "headline_evals_min": min(run.headline_evals for run in self.runs),
            "best_policy_mean": statistics.fmean(best_policy) if best_policy else None,
            "best_policy_std": statistics.stdev(best_policy) if len(best_policy) > 1 else None,
            "best_policy_n": len(best_policy),
            "best_evaluated_mean": statistics.fmean(best_evaluated) if best_evaluated else None,
            "best_evaluated_std": statistics.stdev(best_evaluated) if len(best_evaluated) > 1 else None,
            "best_evaluated_n": len(best_evaluated),
            "final_mean": statistics.fmean(run.final_return for run in self.runs),
            "best_mean": statistics.fmean(run.best_return for run in self.runs),
            "vs_teacher": mean / teacher if teacher else None,
            "frames_to_teacher_median": statistics.median(passed) if passed else None,
            "seeds_past_teacher": f"{len(passed)}/{len(values)}",
            "fall_share": falls / after if after else None,
            "falls": falls,
            "fall_evaluations": after,
        }


def t_ci(values: list[float], confidence: float = 0.95) -> tuple[float | None, float | None]:
    """Student-t CI of the mean, ``mean ± t(n - 1) * std / sqrt(n)``: (None, None) for fewer than 2 values.

    With the 2-5 seeds of a cell, a bootstrap interval can only draw resamples of those few values
    (with 2, its limits are the two values themselves) and covers far less than it claims; the t
    interval's width is what so few seeds can say.
    """
    if len(values) < 2:
        return None, None
    from scipy.stats import t  # imported here so that reading runs needs no scipy

    mean, half = statistics.fmean(values), 0.0
    if min(values) != max(values):
        half = float(t.ppf((1 + confidence) / 2, len(values) - 1)) * statistics.stdev(values) / math.sqrt(len(values))
    return mean - half, mean + half


# --- reading run folders


def find_run_folders(roots: list[Path]) -> list[Path]:
    """Every folder under ``roots`` holding a ``config.yaml``, not looking inside hidden folders or runs.

    Raises:
        FileNotFoundError: a root that does not exist or holds no run folder.
    """
    found = []
    for root in roots:
        if not root.is_dir():
            raise FileNotFoundError(f"{root} is not a folder")
        before = len(found)
        for folder, dirs, files in os.walk(root):
            if "config.yaml" in files:
                found.append(Path(folder))
                dirs.clear()  # checkpoint/ and logs/ of a run hold no runs
            else:
                dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        if len(found) == before:
            raise FileNotFoundError(f"{root} holds no run folder (a folder with config.yaml)")
    return sorted(set(found))


def find_matrix(folder: Path) -> Path | None:
    """The nearest folder above ``folder`` holding ``run_matrix.py``'s ``matrix.json``."""
    for parent in folder.resolve().parents:
        if (parent / "matrix.json").is_file():
            return parent
    return None


def teacher_label(folder: Path, config: dict) -> str:
    """The teacher folder under a matrix root, else the teacher file's name (``shipped``: the default)."""
    matrix = find_matrix(folder)
    if matrix is not None:
        return folder.resolve().relative_to(matrix).parts[0]
    path = (config.get("teacher") or {}).get("path")
    return "shipped" if not path else Path(path).name.removesuffix(".npz").removesuffix(".pt")


def load_run(folder: Path) -> Run:
    """Reads a run folder; ``problem`` says why it does not count, if it does not.

    Raises:
        ValueError: a ``config.yaml`` that is not a ``sail_td3.py`` config.
    """
    try:
        config = yaml.safe_load((folder / "config.yaml").read_text())
        env, method, seed = config["env"]["name"], config["algo"]["name"], int(config["seed"])
    except (yaml.YAMLError, KeyError, TypeError, ValueError) as err:
        raise ValueError(
            f"{folder / 'config.yaml'} is not a sail_td3.py run config (env.name, algo.name, seed): {err}"
        ) from err
    summary, problem = None, None
    if (folder / "summary.json").exists():
        try:
            summary = json.loads((folder / "summary.json").read_text())
        except json.JSONDecodeError as err:
            problem = f"unreadable summary.json ({err})"
    # the eval curve by frames, the last row of a frame kept (a frame logged twice counts once)
    curve = sorted(dict(read_scalar(folder, "eval/return")).items())
    run = Run(folder, env, method, seed, teacher_label(folder, config), config, summary, curve)
    run.problem = problem or unfinished_reason(run)
    if run.problem is None and run.final_return is None:
        run.problem = "finished, but with no eval return (eval.every_frames > total frames?)"
    return run


def unfinished_reason(run: Run) -> str | None:
    """Why ``run`` is unfinished, or None when it is finished (an offline run once it has a summary)."""
    total = (run.config.get("collector") or {}).get("total_frames")
    last_eval = f"last eval at {run.curve[-1][0]} frames" if run.curve else "no eval yet"
    if run.summary is None:
        checkpoint = ", has checkpoint/" if (run.folder / "checkpoint").is_dir() else ""
        return f"unfinished: no summary.json ({last_eval}{checkpoint})"
    if run.offline:
        return None
    frames = run.summary.get("frames")
    if frames is None or (total is not None and frames < total):
        return f"unfinished: {frames} of {total} frames"
    return None


# --- grouping


def group_runs(runs: list[Run]) -> tuple[dict[tuple[str, str, str], Group], list[tuple[str, str]]]:
    """Finished runs by (env, teacher, method), and (folder, why) of the runs left out."""
    groups, left_out, seen = {}, [], {}
    for run in sorted(runs, key=lambda r: str(r.folder)):
        if run.problem is not None:
            left_out.append((shown(run.folder), run.problem))
            continue
        key = (run.env, run.teacher, run.method)
        if (key, run.seed) in seen:  # e.g. the same run copied twice: counting both would weigh it double
            left_out.append(
                (
                    shown(run.folder),
                    f"duplicate of {seen[key, run.seed]} (same env, teacher, method, seed {run.seed}), not counted",
                )
            )
            continue
        seen[key, run.seed] = run.folder
        groups.setdefault(key, Group(*key)).runs.append(run)
    return groups, left_out


def read_matrix(root: Path) -> dict:
    """``run_matrix.py``'s record of the sweeps asked for under ``root``."""
    path = root / "matrix.json"
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(f"{path} is not valid JSON ({err}); rerun run_matrix.py or delete it") from err


def inside(path: Path, folder: Path) -> bool:
    """Whether ``path`` is ``folder`` or below it."""
    path, folder = path.resolve(), folder.resolve()
    return path == folder or folder in path.parents


def shown(path: Path) -> str:
    """``path`` relative to the working directory when it is below it (reports name no machine paths)."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def missing_runs(
    runs: list[Run], roots: list[Path], expect_methods: list[str] = (), expect_seeds: list[int] = ()
) -> list[tuple[str, str]]:
    """(where, why) of each expected run without a run folder.

    Under a ``run_matrix.py`` folder, every teacher x env x method x seed of the sweeps in its
    ``matrix.json`` whose folder is within one of ``roots`` is expected; elsewhere,
    per (env, teacher) seen, every method and seed seen there. ``expect_*`` replace the methods
    and seeds expected.
    """
    present = defaultdict(set)  # matrix root (None: none) -> {(env, teacher, method, seed)}
    for run in runs:
        present[find_matrix(run.folder)].add((run.env, run.teacher, run.method, run.seed))
    missing = []
    for root, cells in present.items():
        expected = set()
        if root is None:
            for env, teacher in {(env, teacher) for env, teacher, _, _ in cells}:
                pair = [(method, seed) for e, t, method, seed in cells if (e, t) == (env, teacher)]
                methods = expect_methods or {method for method, _ in pair}
                seeds = expect_seeds or {seed for _, seed in pair}
                expected |= {(env, teacher, method, seed) for method in methods for seed in seeds}
        else:
            for sweep in read_matrix(root).get("sweeps", []):
                expected |= {
                    (env, sweep["teacher"], method, seed)
                    for env in sweep["envs"]
                    for method in expect_methods or sweep["methods"]
                    for seed in expect_seeds or sweep["seeds"]
                    # only the cells under a folder given (a root below the matrix expects its own cells)
                    if any(inside(root / sweep["teacher"] / env / method / f"seed{seed}", given) for given in roots)
                }
        rank = {method: index for index, method in enumerate(sort_methods(method for _, _, method, _ in expected))}
        for env, teacher, method, seed in sorted(expected - cells, key=lambda c: (c[0], c[1], rank[c[2]], c[3])):
            where = (
                shown(root / teacher / env / method / f"seed{seed}")
                if root
                else f"env {env}, teacher {teacher}, method {method}, seed {seed}"
            )
            missing.append((where, "missing: no run folder"))
    return missing


def config_differences(group: Group) -> dict[str, list]:
    """Config keys that every run of ``group`` has, with values that differ between them (besides
    per-run keys like seed)."""
    flat = [flatten(run.config) for run in group.runs]
    differing = {}
    for key in sorted(set.intersection(*(set(config) for config in flat))):
        if key.startswith(PER_RUN_KEYS):
            continue
        values = {json.dumps(config[key], sort_keys=True) for config in flat}
        if len(values) > 1:
            differing[key] = sorted(values)
    return differing


def config_absences(group: Group) -> dict[tuple[int, ...], dict[str, list]]:
    """Config keys that some runs of ``group`` lack (they ran from a commit before the setting
    existed), grouped by the seeds that lack them: ``{seeds: {key: the others' values}}``."""
    flat = {run.seed: flatten(run.config) for run in group.runs}
    absent: dict[tuple[int, ...], dict[str, list]] = {}
    for key in sorted(set().union(*flat.values()) - set.intersection(*(set(c) for c in flat.values()))):
        if key.startswith(PER_RUN_KEYS):
            continue
        seeds = tuple(sorted(seed for seed, config in flat.items() if key not in config))
        values = {json.dumps(config[key], sort_keys=True) for config in flat.values() if key in config}
        absent.setdefault(seeds, {})[key] = sorted(values)
    return absent


def flatten(config: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in config.items():
        if isinstance(value, dict):
            out.update(flatten(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def sort_methods(methods) -> list[str]:
    """The display order: ``METHOD_ORDER`` first, then the rest alphabetically; a method's budgets
    (``sail (300k)``, ``sail (1M)``) in increasing order."""
    rank = {name: index for index, name in enumerate(METHOD_ORDER)}

    def key(label: str):
        name, _, budget = label.partition(" (")
        return rank.get(name, len(rank)), name, parse_frames(budget.rstrip(")")) if budget else 0

    return sorted(set(methods), key=key)


def frames_label(frames: int) -> str:
    """``300000`` -> ``300k``, ``1000000`` -> ``1M``."""
    if frames % 1_000_000 == 0:
        return f"{frames // 1_000_000}M"
    return f"{frames // 1000}k" if frames % 1000 == 0 else str(frames)


def parse_frames(label: str) -> int:
    """The inverse of :func:`frames_label`."""
    scale = {"k": 1000, "M": 1_000_000}.get(label[-1:], 1)
    return int(float(label.rstrip("kM")) * scale)


def total_frames(run: Run) -> int | None:
    value = (run.config.get("collector") or {}).get("total_frames")
    return None if value is None else int(value)


def label_budgets(runs: list[Run]) -> None:
    """Names each run's method with its budget, ``sail (1M)``, where its (env, teacher, method) has
    runs at several budgets (``collector.total_frames``); the runs of one budget then group apart.
    The method's runs with that teacher on the other envs get their budget too, so that one table
    row (``sail (300k)``) holds one budget on every env."""
    budgets = defaultdict(set)
    for run in runs:
        budgets[run.env, run.teacher, run.method].add(total_frames(run))
    several = {(teacher, method) for (_, teacher, method), values in budgets.items() if len(values) > 1}
    for run in runs:
        if (run.teacher, run.method) in several and total_frames(run) is not None:
            run.method = f"{run.method} ({frames_label(total_frames(run))})"


def ordered_pairs(groups: dict) -> list[tuple[str, str]]:
    """(env, teacher) pairs: envs alphabetically, then teachers by return (Table 2 reads weakest first)."""
    pairs = {(env, teacher): group.teacher_return for (env, teacher, _), group in groups.items()}
    return sorted(pairs, key=lambda pair: (pair[0], pairs[pair] is None, pairs[pair] or 0.0, pair[1]))


# --- outputs


def pair_groups(groups: dict, env: str, teacher: str) -> list[Group]:
    """The groups of one (env, teacher), methods in display order."""
    return [
        groups[env, teacher, method]
        for method in sort_methods(method for (e, t, method) in groups if (e, t) == (env, teacher))
    ]


def rows(groups: dict) -> list[dict]:
    """One row per group, in display order."""
    out = []
    for env, teacher in ordered_pairs(groups):
        for group in pair_groups(groups, env, teacher):
            out.append(
                {
                    "env": env,
                    "teacher": teacher,
                    "teacher_return": group.teacher_return,
                    "method": group.method,
                    "offline": group.offline,
                    **group.stats(),
                }
            )
    return out


def method_name(label: str) -> str:
    """A method's name without its budget: ``sail (1M)`` -> ``sail``."""
    return label.partition(" (")[0]


REPLACED = "sail, replaced default"  # the row name of the SAIL defaults that a confirmed default replaced


def default_envs(groups: dict, default_label: str | None) -> set[str]:
    """The envs with SAIL runs under the confirmed default's own label (``default_label``): there, SAIL's
    runs under the other labels ran with the default it replaced."""
    return {env for env, label, method in groups if label == default_label and method_name(method) == "sail"}


def default_view(groups: dict, teacher: str, default_label: str | None) -> dict:
    """``groups`` as the README and the paper's comparison show ``teacher``'s runs: where the default
    SAIL's runs with that teacher have a label of their own (``default_label``: the campaign's
    ``TABLE1_LABEL``, ``paper-trusted`` once the trusted default replaced the defaults), its ``sail``
    groups stand as ``teacher``'s, and on each env where they do, ``teacher``'s own ``sail`` groups
    become the replaced default's rows (:data:`REPLACED`; on an env the default's label has no run of,
    ``teacher``'s SAIL runs are the default's). Every ``sail`` row then names its budget, ``sail
    (300k)``; a group keeps its own teacher label, which its notes name."""
    if default_label is None or default_label == teacher:
        return groups
    replaced_envs = default_envs(groups, default_label)
    view = {}
    for (env, label, method), group in groups.items():
        if method_name(method) != "sail" or label not in (teacher, default_label):
            view[env, label, method] = group
            continue
        name = REPLACED if label == teacher and env in replaced_envs else "sail"
        frames = total_frames(group.runs[0])
        shown = name if frames is None else f"{name} ({frames_label(frames)})"
        view[env, teacher, shown] = dataclasses.replace(group, method=shown)
    return view


def variant_rows(groups: dict) -> list[dict]:
    """The groups whose teacher label is ``<base>-<variant>`` (a campaign stage's change of one setting:
    ``paper-fifo``, ``random-preact``) where ``<base>`` is another teacher label, each with the group of
    ``<base>`` with the same env, method and budget (``base``: None where there is none)."""
    labels = {teacher for _, teacher, _ in groups}
    by_budget = {
        (env, teacher, method_name(method), total_frames(group.runs[0])): group
        for (env, teacher, method), group in groups.items()
    }
    out = []
    for (env, teacher, method), group in groups.items():
        base, _, variant = teacher.rpartition("-")
        if base in labels:
            key = (env, base, method_name(method), total_frames(group.runs[0]))
            out.append({"env": env, "teacher": base, "variant": variant, "group": group, "base": by_budget.get(key)})
    rank = {name: index for index, name in enumerate(sort_methods(g.method for g in groups.values()))}
    return sorted(out, key=lambda row: (row["env"], row["teacher"], rank[row["group"].method], row["variant"]))


# The headline (mean of each run's last 5 evals, over seeds) first after the group's key.
CSV_COLUMNS = (
    "env",
    "teacher",
    "method",
    f"{HEADLINE}_mean",
    f"{HEADLINE}_std",
    "ci95_low",
    "ci95_high",
    "best_policy_mean",
    "best_policy_std",
    "best_policy_n",
    "best_evaluated_mean",
    "best_evaluated_std",
    "best_evaluated_n",
    "n_seeds",
    "seeds",
    "final_mean",
    "best_mean",
    "teacher_return",
    "vs_teacher",
    "frames_to_teacher_median",
    "seeds_past_teacher",
    "fall_share",
    "falls",
    "fall_evaluations",
    "headline_evals_min",
    "offline",
)


def csv_text(table: list[dict]) -> str:
    """``results.csv``: full precision, ``n/a`` where a value is undefined (pandas reads it as NaN)."""
    file = io.StringIO(newline="")
    writer = csv.writer(file)
    writer.writerow(CSV_COLUMNS)
    for row in table:
        values = {
            **row,
            f"{HEADLINE}_mean": row["headline_mean"],
            f"{HEADLINE}_std": row["headline_std"],
            "seeds": " ".join(map(str, row["seeds"])),
        }
        writer.writerow([NA if values[column] is None else values[column] for column in CSV_COLUMNS])
    return file.getvalue()


def fmt(value: float | None, digits: int = 1) -> str:
    return NA if value is None else f"{value:.{digits}f}"


def fmt_fall(share: float | None, falls: int | None, evaluations: int | None) -> str:
    """``18.6% (13/70)``; ``n/a`` when no run passed, ``n/a (0/0)`` when none evaluated after passing."""
    if falls is None:
        return NA
    return f"{NA if share is None else f'{100 * share:.1f}%'} ({falls}/{evaluations})"


def group_fall(stats: dict) -> str:
    """:func:`fmt_fall` of a group's pooled fall share (:meth:`Group.stats`)."""
    return fmt_fall(stats["fall_share"], stats["falls"], stats["fall_evaluations"])


def best_policy_cell(stats: dict) -> str:
    """The best policy's mean ± std over seeds as the headline is shown, with "k/n seeds" when only
    some seeds evaluated it; ``-`` when none did."""
    if not stats["best_policy_n"]:
        return "-"
    std = "" if stats["best_policy_std"] is None else f" ± {fmt(stats['best_policy_std'])}"
    some = f" ({stats['best_policy_n']}/{stats['n_seeds']} seeds)" if stats["best_policy_n"] < stats["n_seeds"] else ""
    return f"{fmt(stats['best_policy_mean'])}{std}{some}"


def run_details(run: Run) -> str:
    """A finished run's own figures, in Markdown: its eval curve, when it first passed the teacher
    and its fall share since, best and final evaluation, best logged training return, alpha switch,
    promotions and final threshold C, its best policy's evaluation, frames/s and peak memory (what
    ``summary.json`` holds of them)."""
    summary, evals = run.summary or {}, run.curve
    train = read_scalar(run.folder, "train/dense_return")
    frames = summary.get("frames", 0)
    teacher = run.teacher_return
    passed = run.passed_teacher_at()
    lines = [
        f"### `{shown(run.folder)}`: {run.env}, {run.method}, teacher {run.teacher}, seed {run.seed}, "
        f"{frames // 1000}k frames",
        "",
    ]
    if evals:
        lines += [
            "| frames | " + " | ".join(f"{frame // 1000}k" for frame, _ in evals) + " |",
            "|---|" + "---|" * len(evals),
            "| eval return | " + " | ".join(f"{value:.0f}" for _, value in evals) + " |",
            "",
        ]
    if teacher is not None:
        share = run.fall_share
        lines.append(
            f"- teacher return {teacher:.1f}; "
            + (
                f"eval first above it at {passed // 1000}k frames"
                if passed is not None
                else f"no eval above it within {frames // 1000}k frames"
            )
            + (
                ""
                if share is None
                else f"; later evals below it: {fmt_fall(share['share'], share['falls'], share['evaluations'])}"
            )
        )
    lines.append(
        f"- best eval {fmt(run.best_return, 0)}, final eval {fmt(run.final_return, 0)}"
        if run.final_return is not None
        else "- no evals"
    )
    lines.append(
        f"- best training-episode mean return logged {max(v for _, v in train):.0f}"
        if train
        else "- no training returns"
    )
    if "num_promoted" in summary:
        threshold = summary.get("teacher_threshold")
        lines.append(
            f"- alpha switched (first promotion) at {summary.get('alpha_switched_at_frame')} frames; "
            f"{summary['num_promoted']} promoted"
            + ("" if threshold is None else f"; final threshold C = {threshold:.0f}")
        )
    if run.best_policy_return is not None:
        best = summary["best_policy"]
        lines.append(
            f"- best policy (kept at {best.get('frames')} frames, training-return mean "
            f"{fmt(best.get('train_return_mean'), 0)}): eval {run.best_policy_return:.0f} over "
            f"{best.get('episodes')} episodes"
        )
    if run.best_evaluated_return is not None:
        best = summary["best_evaluated_policy"]
        lines.append(
            f"- best evaluated policy (kept at {best.get('frames')} frames, evaluated "
            f"{fmt(best.get('periodic_eval_return'), 0)} then): eval {run.best_evaluated_return:.0f} over "
            f"{best.get('episodes')} other episodes"
        )
    speed = summary.get("frames_per_second")
    memory = summary.get("peak_memory_mb")
    if speed is not None or memory is not None:
        lines.append(f"- {fmt(speed)} frames/s (since the last start), peak RSS {fmt(memory, 0)} MB")
    return "\n".join(lines)


def variants_markdown(variants: list[dict]) -> list[str]:
    """The "Variants" section of ``results.md``: each variant's cell beside its base's."""
    return [
        "## Variants beside their base",
        "",
        "A teacher label `<base>-<variant>` is one campaign stage's change of one setting (`paper-fifo`: the "
        "teacher buffer's rule; `random-preact`: the pre-tanh penalty), run with the teacher of `<base>`. Each "
        f"is set beside the runs of `<base>` with the same env, method and budget: last-{HEADLINE_EVALS} mean "
        "± std over seeds, that mean over the teacher's return, and the fall share (as in the table above); "
        "Welch p: the two-sided p-value of Welch's t-test on the two sets of seeds' last-5 means (n/a with "
        "fewer than 2 seeds on a side).",
        "",
        *variant_table_lines(variants),
    ]


def variant_table_lines(variants: list[dict]) -> list[str]:
    """The table of :func:`variants_markdown`: one line per variant (:func:`variant_rows`)."""
    lines = [
        f"| env | teacher (return) | method | variant | last-{HEADLINE_EVALS} mean ± std | vs teacher | fall share "
        f"| base: last-{HEADLINE_EVALS} mean ± std | base: vs teacher | base: fall share | Welch p |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in variants:
        group, base = row["group"], row["base"]
        stats, base_stats = group.stats(), base.stats() if base else None
        p_value = welch(group.values, base.values)[1] if base else None
        lines.append(
            f"| {row['env']} | {row['teacher']} ({fmt(group.teacher_return)}) | {group.method} | {row['variant']} "
            f"| {readme_cell(group)} | {fmt(stats['vs_teacher'], 2)} | {group_fall(stats)} | {readme_cell(base)} "
            f"| {fmt(base_stats['vs_teacher'], 2) if base else '-'} | {group_fall(base_stats) if base else '-'} "
            f"| {fmt(p_value, 2) if base else '-'} |"
        )
    return lines


def welch(first: list[float], second: list[float]) -> tuple[float | None, float | None]:
    """Welch's t-test of two samples' means: (t, two-sided p), (None, None) with fewer than 2 values on
    a side or no spread on either (t undefined)."""
    if len(first) < 2 or len(second) < 2 or (statistics.stdev(first) == 0 and statistics.stdev(second) == 0):
        return None, None
    from scipy.stats import ttest_ind  # imported here so that reading runs needs no scipy

    result = ttest_ind(first, second, equal_var=False)
    return float(result.statistic), float(result.pvalue)


def markdown(
    table: list[dict],
    left_out: list[tuple[str, str]],
    notes: list[str],
    curves: list[Path],
    details: list[str] = (),
    variants: list[dict] = (),
) -> str:
    """``results.md``: the table, the variants beside their base (:func:`variant_rows`), the runs left
    out, notes on the groups, the curve files, and the per-run ``details`` (:func:`run_details`) if any."""
    lines = [
        f"Headline: the mean of each run's last {HEADLINE_EVALS} deterministic evaluations (each the mean "
        f"return of eval.episodes episodes), over seeds: mean ± sample std (ddof=1; n/a for one seed) and "
        "its 95% Student-t CI (mean ± t(n - 1) std / sqrt(n); n/a for one seed). "
        "† a seed had fewer evaluations, all of them averaged (see Notes). Best policy: the evaluation of "
        "the policy each run kept by its own training returns (summary.json's best_policy), mean ± sample std "
        "over the seeds that evaluated it (k/n seeds when not all did; - when none did). Final and best: the mean "
        "over seeds of each run's last and highest evaluation. vs teacher: headline mean / teacher return. "
        "Frames to pass teacher: the frames at a run's first evaluation above the teacher's return, median "
        "over the seeds that passed (of an even count, the mean of the middle two). Fall share: of the "
        "evaluations after a run's first one above the teacher's return, the share below it, pooled over the "
        "seeds that passed (falls/evaluations; n/a if none passed, n/a (0/0) if they passed only at their "
        "last evaluation). Best headline mean per env and teacher in bold.",
        "",
        *table_lines(table),
    ]
    if variants:
        lines += ["", *variants_markdown(variants)]
    lines += ["", "## Missing or unfinished runs", ""]
    lines += [f"- `{where}`: {why}" for where, why in left_out] or ["None."]
    if notes:
        lines += ["", "## Notes", "", *[f"- {note}" for note in notes]]
    if curves:
        lines += ["", "## Learning curves", "", *[f"- [{path.name}]({path.name})" for path in curves]]
    if details:
        lines += ["", "## Runs", ""]
        for text in details:
            lines += [text, ""]
        lines.pop()
    return "\n".join(lines) + "\n"


def table_lines(table: list[dict]) -> list[str]:
    """The results table of :func:`markdown` for the rows ``table`` (:func:`rows`), the best headline
    mean per env and teacher in bold."""
    best, methods = {}, defaultdict(int)  # per (env, teacher): the best headline mean, the number of methods
    for row in table:
        key = (row["env"], row["teacher"])
        best[key], methods[key] = max(best.get(key, -math.inf), row["headline_mean"]), methods[key] + 1
    lines = [
        f"| env | teacher (return) | method | last-{HEADLINE_EVALS} mean ± std | best policy | 95% CI | seeds "
        "| final | best | vs teacher | frames to pass teacher | fall share |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in table:
        mean = fmt(row["headline_mean"])
        if row["headline_mean"] == best[row["env"], row["teacher"]] and methods[row["env"], row["teacher"]] > 1:
            mean = f"**{mean}**"
        std = "" if row["headline_std"] is None else f" ± {fmt(row['headline_std'])}"
        short = " †" if row["headline_evals_min"] < HEADLINE_EVALS else ""
        ci = NA if row["ci95_low"] is None else f"[{fmt(row['ci95_low'])}, {fmt(row['ci95_high'])}]"
        passed = (
            "offline"
            if row["offline"]
            else f"{fmt(row['frames_to_teacher_median'], 0)} ({row['seeds_past_teacher']} seeds passed)"
        )
        fall = "offline" if row["offline"] else group_fall(row)
        lines.append(
            f"| {row['env']} | {row['teacher']} ({fmt(row['teacher_return'])}) | {row['method']} | "
            f"{mean}{std}{short} | {best_policy_cell(row)} | {ci} | {row['n_seeds']} | {fmt(row['final_mean'])} | "
            f"{fmt(row['best_mean'])} | {fmt(row['vs_teacher'], 2)} | {passed} | {fall} |"
        )
    return lines


def aligned_curves(runs: list[Run]) -> tuple[np.ndarray, np.ndarray]:
    """(frames, returns[seed, frame]) on the eval frames every seed has.

    Seeds evaluated at different frames (another ``eval.every_frames``, or a resumed run that
    re-evaluated elsewhere) are compared only where they all were: the intersection.
    """
    common = sorted(set.intersection(*(set(frames for frames, _ in run.curve) for run in runs)))
    values = np.array([[dict(run.curve)[frames] for frames in common] for run in runs], dtype=float)
    return np.array(common, dtype=float), values.reshape(len(runs), len(common))


def draw_groups(ax, groups: list[Group], colour_of) -> None:
    """On ``ax``: each group's mean eval return over seeds with a min-max band (offline methods as a
    dotted level), coloured by ``colour_of(index, group)``, and the teacher's return dashed."""
    for index, group in enumerate(groups):
        colour, n = colour_of(index, group), len(group.runs)
        if group.offline:
            ax.axhline(statistics.fmean(group.values), ls=":", c=colour, label=f"{group.method} (offline, n={n})")
            continue
        frames, values = aligned_curves(group.runs)
        if not len(frames):
            continue
        ax.plot(frames, values.mean(axis=0), c=colour, label=f"{group.method} (n={n})")
        if n > 1:
            ax.fill_between(frames, values.min(axis=0), values.max(axis=0), color=colour, alpha=0.2, lw=0)
    teacher_return = groups[0].teacher_return if groups else None
    if teacher_return is not None:
        ax.axhline(teacher_return, ls="--", c="gray", label=f"teacher ({teacher_return:.0f})")


def plot_curves(path: Path, env: str, teacher: str, groups: list[Group]) -> None:
    """Figure 2 style: mean eval return over seeds with a min-max band per method, the teacher dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colours = plt.get_cmap("tab20" if len(groups) > 10 else "tab10")
    fig, ax = plt.subplots(figsize=(7, 4.5))
    draw_groups(ax, groups, lambda index, group: colours(index))
    ax.set(xlabel="environment frames", ylabel="eval return (deterministic)")
    ax.set_title(f"{env}, teacher {teacher}\nmean over seeds, band: min to max", fontsize=10)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _operational(key: str) -> bool:
    """Whether the dotted config ``key`` is one of :data:`OPERATIONAL_RESUME_KEYS` or below one."""
    return any(key == k or key.startswith(k + ".") for k in OPERATIONAL_RESUME_KEYS)


def resume_notes(group: Group) -> list[str]:
    """The seeds of a group continued with other settings (``summary.json``'s ``resumes``, less
    :data:`OPERATIONAL_RESUME_KEYS`), one note per resume that changed any."""
    name, notes = f"{group.env} / {group.teacher} / {group.method}", []
    for run in sorted(group.runs, key=lambda r: r.seed):
        for resume in (run.summary or {}).get("resumes", []):
            changes = [
                f"{key} {old!r} -> {new!r}" for key, (old, new) in resume["changes"].items() if not _operational(key)
            ]
            # and the settings another version added (the checkpoint's config lacked them) or removed
            for kind, label in (("added", "new"), ("removed", "removed")):
                changes += [
                    f"{key} ({label}) {value!r}" for key, value in resume.get(kind, {}).items() if not _operational(key)
                ]
            if changes:
                notes.append(f"{name}: seed {run.seed} went on from frame {resume['frames']} with {', '.join(changes)}")
    return notes


def group_notes(group: Group) -> list[str]:
    """Everything a reader of a group's headline should know: :func:`headline_notes`,
    :func:`resume_notes`, seeds with other teacher returns, seeds without a best-policy evaluation
    where others have one, seeds with other settings."""
    name = f"{group.env} / {group.teacher} / {group.method}"
    notes = headline_notes(group) + resume_notes(group)
    returns = {run.teacher_return for run in group.runs}
    if len(returns) > 1:
        notes.append(
            f"{name}: the seeds' teacher returns differ ({sorted(r for r in returns if r is not None)}); "
            "the table shows their median"
        )
    lacking = sorted(run.seed for run in group.runs if run.best_policy_return is None)
    if 0 < len(lacking) < len(group.runs):  # the best-policy column then averages fewer seeds than the headline
        notes.append(
            f"{name}: the best policy averages {len(group.runs) - len(lacking)} of {len(group.runs)} seeds; "
            f"seed{'s' * (len(lacking) > 1)} {', '.join(map(str, lacking))} did not evaluate one "
            "(runs before best_policy, or eval.best_policy.episodes=0)"
        )
    for key, values in config_differences(group).items():
        notes.append(f"{name}: the seeds differ in {key} ({', '.join(values)}); they are averaged together")
    for seeds, keys in config_absences(group).items():
        settings = ", ".join(f"{key} ({', '.join(values)})" for key, values in keys.items())
        which = f"seed{'s' * (len(seeds) > 1)} {', '.join(map(str, seeds))}"
        notes.append(
            f"{name}: the configs of {which} lack settings the others have: {settings}; they are averaged together"
        )
    return notes


def headline_notes(group: Group) -> list[str]:
    """Notes on the evaluations behind a group's headline: seeds with fewer than ``HEADLINE_EVALS``
    evaluations, and evaluations of another number of episodes than the spec's."""
    name, notes = f"{group.env} / {group.teacher} / {group.method}", []
    short = [run for run in group.runs if run.headline_evals < HEADLINE_EVALS]
    if short:

        def evals(run: Run) -> str:
            detail = " (offline)" if run.offline else "" if run.curve else " (no eval CSV: summary.json's final eval)"
            return f"seed {run.seed}: {run.headline_evals}{detail}"

        seeds = "; ".join(evals(run) for run in sorted(short, key=lambda r: r.seed))
        notes.append(
            f"{name}: fewer than {HEADLINE_EVALS} evaluations, so the headline averages all of them "
            f"(evaluations per seed: {seeds})"
        )
    episodes = sorted({run.eval_episodes for run in group.runs if run.eval_episodes not in (None, SPEC_EVAL_EPISODES)})
    if episodes:
        notes.append(
            f"{name}: evaluations of eval.episodes={', '.join(map(str, episodes))} episodes "
            f"(the reporting spec asks for {SPEC_EVAL_EPISODES})"
        )
    return notes


def paper_env(env: str) -> str:
    """Table 1's name of a gymnasium id: ``Hopper-v4`` -> ``Hopper``."""
    return env.split("-v")[0]


def table1_order(env: str) -> tuple[int, str]:
    """The sort key of a gymnasium id in Table 1's env order (other envs after, alphabetically)."""
    rank = PAPER_ENVS.index(paper_env(env)) if paper_env(env) in PAPER_ENVS else len(PAPER_ENVS)
    return rank, env


def readme_envs(groups: dict, teacher: str) -> list[str]:
    """The envs with runs of ``teacher``, in Table 1's order (others after, alphabetically)."""
    return sorted({env for env, label, _ in groups if label == teacher}, key=table1_order)


def plot_panels(path: Path, teacher: str, envs: list[str], groups: dict, methods=None) -> None:
    """One panel per env: each method's mean eval return over seeds with a min-max band, the teacher dashed.

    Args:
        path: the PNG to write.
        teacher: the teacher label whose runs are drawn.
        envs: one panel each, in this order.
        groups: :attr:`Source.groups`.
        methods: the method names to draw (every budget of each); None: every method.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = sort_methods(
        label for (env, t, label) in groups if t == teacher and (methods is None or method_name(label) in methods)
    )
    colours = {label: plt.get_cmap("tab10")(index % 10) for index, label in enumerate(labels)}
    columns = min(2, len(envs))
    rows_ = math.ceil(len(envs) / columns)
    fig, axes = plt.subplots(rows_, columns, figsize=(5.5 * columns, 3.6 * rows_), squeeze=False)
    # a method keeps its colour across the panels; the grid may have more panels than envs
    for ax, env in zip(axes.flat, envs, strict=False):
        shown = [group for group in pair_groups(groups, env, teacher) if group.method in colours]
        draw_groups(ax, shown, lambda index, group: colours[group.method])
        ax.set_title(env, fontsize=10)
        ax.set(xlabel="environment frames", ylabel="eval return")
        ax.legend(loc="best", fontsize=7)
    for ax in list(axes.flat)[len(envs) :]:
        ax.set_visible(False)
    fig.suptitle(f"teacher: {teacher}; mean over seeds, band: min to max", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def readme_cell(group: Group | None) -> str:
    if group is None:
        return "-"
    stats = group.stats()
    if stats["n_seeds"] == 1:
        return f"{fmt(stats['headline_mean'])} (1 seed)"
    return f"{fmt(stats['headline_mean'])} ± {fmt(stats['headline_std'])} ({stats['n_seeds']} seeds)"


@functools.cache
def script_of(method: str) -> Path:
    """``run_matrix.script_for``, once per method: it composes the config of every method each call."""
    return sibling("run_matrix").script_for(method)  # puts examples/ on sys.path


# A learner's own section of ``algo``: compared only in the runs of that learner (``algo.sac`` of a TD3
# run is never read)
LEARNER_SECTIONS = ("sac", "ppo", "bc")
# Keys a command always shows (cell_command), or never (per-run and operational: what a run learns and
# how it is evaluated do not depend on them)
COMMAND_KEYS = ("collector.total_frames", "eval.episodes", "eval.every_frames", *PER_RUN_KEYS, "checkpoint.")


def examples_module(name: str):
    """``examples/<name>.py`` as a module (``config_schema``: the scripts' typed config)."""
    if str(REPO / "examples") not in sys.path:
        sys.path.insert(0, str(REPO / "examples"))
    return importlib.import_module(name)


@functools.cache
def defaults_of(method: str, env: str) -> dict | None:
    """The config ``algo=<method> env=<env>`` composes now, as a plain container (interpolations
    resolved, enums as their names); None where ``conf/`` has no such method or env."""
    from hydra import compose, initialize_config_dir
    from hydra.errors import MissingConfigException
    from omegaconf import OmegaConf

    examples_module("config_schema").register_config_schema()
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base="1.3"):
        try:
            config = compose("config", overrides=[f"algo={method}", f"env={env}"])
        except MissingConfigException:
            return None
        return OmegaConf.to_container(config, resolve=True, enum_to_str=True)


def override_value(value) -> str:
    """A config value as a Hydra override writes it: ``true``, ``null``, ``[400,300]``, ``{a:1}``, ``0.001``."""
    if isinstance(value, bool):
        return str(value).lower()
    if value is None:
        return "null"
    if isinstance(value, list | tuple):
        return "[" + ",".join(override_value(item) for item in value) + "]"
    if isinstance(value, dict):
        return "{" + ",".join(f"{key}:{override_value(item)}" for key, item in value.items()) + "}"
    return sibling("run_matrix").hydra_value(str(value))


def changed_settings(run: Run) -> list[str]:
    """The overrides that turn what ``algo=<method> env=<env>`` composes now into what the run ran with
    (``config_schema.with_saved_before``): ``key=value`` for each setting that differs, in key order, a section switched
    on or off and ``env.kwargs`` as whole values (``harness.config_changes``). Not compared:
    :data:`COMMAND_KEYS` and another learner's section (:data:`LEARNER_SECTIONS`)."""
    config = run.config
    defaults = defaults_of(config["algo"]["name"], run.env)
    if defaults is None:
        return []
    learner = (config.get("algo") or {}).get("learner") or defaults["algo"]["learner"]
    skipped = (*COMMAND_KEYS, *(f"algo.{name}." for name in LEARNER_SECTIONS if name != learner))
    changes = config_changes(examples_module("config_schema").with_saved_before(config), defaults)
    return [f"{key}={override_value(ran)}" for key, (ran, _) in changes.items() if not f"{key}.".startswith(skipped)]


def cell_command(group: Group) -> str:
    """The training command of a group's runs, from their config (seeds as ``<0|1|2>``): the settings
    that differ from what the method composes now (:func:`changed_settings`, of the first seed's run)
    follow the budget, threads and evaluation."""
    run = group.runs[0]
    config = run.config
    method = config["algo"]["name"]  # the row may be named otherwise (the replaced default's)
    seeds = "|".join(str(seed) for seed in sorted(r.seed for r in group.runs))
    teacher = (config.get("teacher") or {}).get("path")
    args = [
        f"python {script_of(method).relative_to(REPO)}",
        f"algo={method}",
        f"env={run.env}",
        f"seed=<{seeds}>" if len(group.runs) > 1 else f"seed={seeds}",
        f"collector.total_frames={total_frames(run)}",
        f"threads={config.get('threads')}",
        f"eval.episodes={(config.get('eval') or {}).get('episodes')}",
        f"eval.every_frames={(config.get('eval') or {}).get('every_frames')}",
        *changed_settings(run),
        *([f"teacher.path=<teachers>/{Path(teacher).name}"] if teacher else []),
    ]
    return " ".join(args)


def listed(items: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} and {items[-1]}"


def group_of(groups: dict, env: str, teacher: str, method: str, frames: int) -> Group | None:
    """The group of ``method``'s runs of ``frames`` frames (whatever its budget label) with ``teacher`` on ``env``."""
    return next(
        (
            group
            for (e, t, label), group in groups.items()
            if (e, t) == (env, teacher) and method_name(label) == method and total_frames(group.runs[0]) == frames
        ),
        None,
    )


def passes_phrase(method: str, groups: list[Group]) -> str:
    """How many seeds of ``method`` passed their teacher, per env: every seed, k of n, none."""
    counts = [
        (group.env, sum(run.passed_teacher_at() is not None for run in group.runs), len(group.runs)) for group in groups
    ]
    every = [env for env, passed, n in counts if passed == n]
    parts = [f"on every seed on {listed(every)}"] if every else []
    some = {}  # (passed, seeds) -> envs, in env order
    for env, passed, n in counts:
        if passed < n:
            some.setdefault((passed, n), []).append(env)
    parts += [
        f"on {passed or 'none'} of {n} seed{'s' if n > 1 else ''} on {listed(envs)}"
        for (passed, n), envs in some.items()
    ]
    return (
        f"`{method}` passes its teacher {parts[0] if len(parts) == 1 else ', '.join(parts[:-1]) + ', and ' + parts[-1]}"
    )


STANDING_FRAMES = 300_000  # the budget of the README's claims on SAIL against DAC


def standing(groups: dict, teacher: str, envs: list[str], first: str = "sail", second: str = "dac") -> list[str]:
    """The README's claims on ``first`` against ``second`` (their runs of :data:`STANDING_FRAMES` frames with
    ``teacher``), made from the runs so that they follow the seeds collected: on which envs every seed
    passed its teacher, and where every seed of one ends (last-5) above every seed of the other."""
    pairs = [
        (
            env,
            group_of(groups, env, teacher, first, STANDING_FRAMES),
            group_of(groups, env, teacher, second, STANDING_FRAMES),
        )
        for env in envs
    ]
    pairs = [(env, a, b) for env, a, b in pairs if a is not None and b is not None]
    if not pairs:
        return []
    above = [env for env, a, b in pairs if min(a.values) > max(b.values)]
    below = [env for env, a, b in pairs if max(a.values) < min(b.values)]
    overlap = [env for env, _, _ in pairs if env not in above + below]
    order = []
    if above:
        order.append(f"every `{first}` seed ends above every `{second}` seed on {listed(above)}")
    if below:
        order.append(f"every `{second}` seed ends above every `{first}` seed on {listed(below)}")
    if overlap:
        order.append(f"their seeds overlap on {listed(overlap)}")
    text = (
        f"At {frames_label(STANDING_FRAMES)} frames, {passes_phrase(first, [a for _, a, _ in pairs])}; "
        f"{passes_phrase(second, [b for _, _, b in pairs])}. By last-5, {'; '.join(order)}."
    )
    return [text, ""]


def measure_rows(method: str, row: list[Group | None]) -> list[str]:
    """The README's rows under a method of :data:`MEASURED`: its best policy (mean ± std over the seeds
    that kept one) and its fall share (pooled over the seeds that passed), each where some env has one."""
    stats = [None if group is None else group.stats() for group in row]
    best = ["-" if st is None else best_policy_cell(st) for st in stats]
    falls = ["-" if st is None else group_fall(st) for st in stats]
    return [
        f"| {method}: {name} | " + " | ".join(cells) + " |"
        for name, cells in (("best policy", best), ("fall share", falls))
        if any(cell not in ("-", NA) for cell in cells)
    ]


def readme_section(groups: dict, teacher: str, figure: str, report: str = "results.md") -> str:
    """The README's results section for the runs of ``teacher`` (see the module docstring); ``figure``
    and ``report`` (the aggregate's ``results.md``, where the notes are) as links from the README.
    ``groups`` as :func:`default_view` gives them: a replaced default's rows are named so."""
    envs = readme_envs(groups, teacher)
    methods = sort_methods(method for (env, label, method) in groups if label == teacher)
    header = "| method | " + " | ".join(envs) + " |"
    lines = [header, "|---" * (len(envs) + 1) + "|"]
    for method in methods:
        row = [groups.get((env, teacher, method)) for env in envs]
        lines.append(f"| {method} | " + " | ".join(readme_cell(group) for group in row) + " |")
        if method_name(method) in MEASURED:
            lines += measure_rows(method, row)
    teachers = [pair_groups(groups, env, teacher)[0].teacher_return for env in envs]
    lines.append("| teacher | " + " | ".join(fmt(value) for value in teachers) + " |")
    paper = [PAPER_SAIL.get(paper_env(env)) for env in envs]
    lines.append(
        "| SAIL in the paper (1M frames, -v2 envs) | "
        + " | ".join("-" if value is None else f"{value[0]} ± {value[1]}" for value in paper)
        + " |"
    )
    runs = [run for (e, t, _), group in groups.items() if t == teacher for run in group.runs]
    budgets = sorted({total_frames(run) for run in runs if not run.offline and total_frames(run)})
    cpus = sorted({((run.summary or {}).get("provenance") or {}).get("cpu_model") or "unknown" for run in runs})
    threads = sorted({((run.summary or {}).get("provenance") or {}).get("torch_threads") for run in runs} - {None})
    # each run's recorded wall time; for runs without one (earlier versions), its frames over its
    # frames per second since its last start
    trained = [run for run in runs if not run.offline and run.summary]
    recorded = [run.summary["wall_seconds"] for run in trained if run.summary.get("wall_seconds") is not None]
    estimated = [
        total_frames(run) / run.summary["frames_per_second"]
        for run in trained
        if run.summary.get("wall_seconds") is None and run.summary.get("frames_per_second")
    ]
    hours = (sum(recorded) + sum(estimated)) / 3600
    if not estimated:
        how = "each run's recorded training time"
    elif not recorded:
        how = "estimated: each run's frames over its frames per second"
    else:
        how = f"recorded per run; estimated for {len(estimated)} runs as their frames over their frames per second"
    commands = [cell_command(group) for env in envs for group in pair_groups(groups, env, teacher)]
    episodes = "/".join(str(n) for n in sorted({run.eval_episodes for run in runs} - {None}))
    shown = [group for (e, t, _), group in groups.items() if t == teacher]
    offline = sorted({group.method for group in shown if all(run.offline for run in group.runs)})
    # an offline method's one evaluation is said above: its headline notes would only repeat it
    notes = [
        note
        for group in shown
        for note in group_notes(group)
        if group.method not in offline or note not in headline_notes(group)
    ]
    # what the rows under a method of MEASURED say, for the kinds of row the table has
    kinds = {
        "best policy": "the policy each run kept by the SAIL authors' rule (the best mean return of its last 100 "
        "training episodes), evaluated on 50 episodes, mean ± std over the seeds that kept one",
        "fall share": "of the evaluations after a run first passed its teacher, those below the teacher's return, "
        "pooled over seeds",
    }
    measured = [f"`<method>: {kind}`, {what}" for kind, what in kinds.items() if any(f": {kind} |" in x for x in lines)]
    replaced = any(method_name(method) == REPLACED for method in methods)
    text = [
        f"Per run, the mean of its last {HEADLINE_EVALS} deterministic evaluations ({episodes} episodes each)"
        + (f"; offline ({', '.join(offline)}), its one evaluation after training" if offline else "")
        + "; per cell, the mean ± std",
        f"over seeds. Budget per run: {', '.join(frames_label(b) + ' frames' for b in budgets)}. CPUs: "
        f"{', '.join(cpus)}, {'/'.join(map(str, threads))} torch thread per run; wall time about {hours:.0f} h "
        f"in all ({how}).",
        *([f"Rows {'; '.join(measured)}."] if measured else []),
        *(
            [
                f"`{REPLACED}`: SAIL with the defaults that the trusted default replaced (the settings in the "
                "commands below)."
            ]
            if replaced
            else []
        ),
        "",
        *lines,
        "",
        *standing(groups, teacher, envs),
        *(
            [f"Notes on these runs ({len(notes)}: fewer evaluations, other settings): [the report]({report}).", ""]
            if notes
            else []
        ),
        f"![Evaluation return against frames, one panel per env]({figure})",
        "",
        "<details><summary>The command of each cell</summary>",
        "",
        "```bash",
        *commands,
        "```",
        "",
        "</details>",
    ]
    return "\n".join(text)


def safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.+-]+", "_", text)


class Source:
    """What a report or a generated block is made from: the run folders under ``roots`` (read on first
    use, once) and ``out``, the report folder that a block's links and figures point to.

    Args:
        roots: folders holding run folders (or, for a block of another study's files, that folder).
        out: the report folder (``results.md``, the PNGs).
        teacher: the teacher label of the blocks that show one teacher's runs.
        expect_methods: list these methods as missing where absent (see :func:`missing_runs`).
        expect_seeds: list these seeds as missing where absent.
        default_label: the teacher label of the default SAIL's runs with ``teacher``'s teacher, where it
            is another (:func:`default_view`); None: ``teacher``.
    """

    def __init__(
        self,
        roots: list[Path],
        out: Path,
        teacher: str = "paper",
        expect_methods: list[str] = (),
        expect_seeds: list[int] = (),
        default_label: str | None = None,
    ) -> None:
        self.roots, self.out, self.teacher = [Path(root) for root in roots], Path(out), teacher
        self.default_label = default_label
        self.expect_methods, self.expect_seeds = list(expect_methods), list(expect_seeds)
        self._read, self._once = None, {}

    def _runs(self) -> tuple[dict, list[tuple[str, str]]]:
        if self._read is None:
            runs = [load_run(folder) for folder in find_run_folders(self.roots)]
            missing = missing_runs(runs, self.roots, self.expect_methods, self.expect_seeds)  # by the matrices' names
            label_budgets(runs)
            groups, left_out = group_runs(runs)
            self._read = groups, missing + left_out
        return self._read

    def once(self, key: str, make: Callable[[], str]) -> str:
        """``make()``, made once per ``key`` (a block that two files hold)."""
        if key not in self._once:
            self._once[key] = make()
        return self._once[key]

    @property
    def groups(self) -> dict[tuple[str, str, str], Group]:
        """The finished runs by (env, teacher, method) (:func:`group_runs`)."""
        return self._runs()[0]

    @property
    def shown(self) -> dict[tuple[str, str, str], Group]:
        """:attr:`groups` as the README and the paper's comparison show ``teacher``'s (:func:`default_view`)."""
        return default_view(self.groups, self.teacher, self.default_label)

    @property
    def left_out(self) -> list[tuple[str, str]]:
        """(where, why) of the runs missing, unfinished or duplicated."""
        return self._runs()[1]

    def curves(self) -> list[Path]:
        """The learning-curve PNGs of the report, one per (env, teacher)."""
        return [
            self.out / f"curves_{safe_name(env)}_{safe_name(teacher)}.png"
            for env, teacher in ordered_pairs(self.groups)
        ]

    def report(self, per_run: bool = False) -> str:
        """``results.md`` (:func:`markdown`); with ``per_run``, each finished run's :func:`run_details` after it."""
        groups = self.groups
        notes = [note for group in groups.values() for note in group_notes(group)]
        runs = sorted((run for group in groups.values() for run in group.runs), key=lambda run: str(run.folder))
        details = [run_details(run) for run in runs] if per_run else []
        return markdown(rows(groups), self.left_out, notes, self.curves(), details, variant_rows(groups))

    def draw_curves(self) -> None:
        """Writes the report's learning curves (:func:`plot_curves`)."""
        self.out.mkdir(parents=True, exist_ok=True)
        for path, (env, teacher) in zip(self.curves(), ordered_pairs(self.groups), strict=True):
            plot_curves(path, env, teacher, pair_groups(self.groups, env, teacher))


# --- generated blocks: tables written into Markdown files between markers


def markers(name: str) -> tuple[str, str]:
    """The lines around the generated block ``name`` in a Markdown file."""
    return f"<!-- aggregate:{name} START -->", f"<!-- aggregate:{name} END -->"


def block_names(text: str) -> list[str]:
    """The names of the generated blocks in ``text``, in order."""
    return re.findall(r"<!-- aggregate:(\S+) START -->", text)


def replace_block(text: str, name: str, block: str, where: str | Path = "the file") -> str:
    """``text`` with what lies between the markers of block ``name`` replaced by ``block`` (a blank line
    on either side).

    Raises:
        ValueError: the markers are not there once each, START before END (``where`` names the file).
    """
    start, end = markers(name)
    if text.count(start) != 1 or text.count(end) != 1 or text.index(start) > text.index(end):
        raise ValueError(f"{where} must have the line {start}, then the line {end}, once each, around its block")
    low, high = text.index(start) + len(start), text.index(end)
    return text[:low] + "\n\n" + block.strip("\n") + "\n\n" + text[high:]


def link(path: Path, target: Path) -> str:
    """``path`` as a relative link from the Markdown file ``target``."""
    return os.path.relpath(Path(path).resolve(), Path(target).resolve().parent)


def figure_in(target: Path, caption: str, path: Path) -> str:
    """The figure ``path`` in the Markdown file ``target``: an image, or, in a page of the docs site
    (which cannot link outside ``docs/``), the figure's path in the repository."""
    if Path(target).resolve().is_relative_to(REPO / "docs"):
        return f"{caption}: `{Path(path).resolve().relative_to(REPO)}`."
    return f"![{caption}]({link(path, target)})"


def sibling(name: str):
    """The script ``benchmarks/<name>.py`` as a module (they import each other by their file names)."""
    if str(BENCHMARKS) not in sys.path:
        sys.path.insert(0, str(BENCHMARKS))
    return importlib.import_module(name)


def readme_figure(source: Source) -> Path:
    return source.out / f"results_{safe_name(source.teacher)}.png"


def block_readme(source: Source, target: Path) -> str:
    """The README's results section for the runs of ``source.teacher`` (:func:`readme_section`)."""
    if not readme_envs(source.shown, source.teacher):
        raise ValueError(f"no finished run with teacher {source.teacher!r} for {target}'s results section")
    figure, report = link(readme_figure(source), target), link(source.out / "results.md", target)
    return readme_section(source.shown, source.teacher, figure, report)


def draw_readme(source: Source) -> None:
    """The README section's figure: one panel per env (:func:`plot_panels`)."""
    source.out.mkdir(parents=True, exist_ok=True)
    plot_panels(readme_figure(source), source.teacher, readme_envs(source.shown, source.teacher), source.shown)


def block_teacher_table(source: Source, target: Path) -> str:
    """The results table (:func:`table_lines`) of every method with ``source.teacher``, SAIL's rows as the
    README shows them (:attr:`Source.shown`)."""
    return "\n".join(table_lines([row for row in rows(source.shown) if row["teacher"] == source.teacher]))


def is_variant(label: str, labels: set[str]) -> bool:
    """Whether a teacher label is ``<base>-<variant>`` of another label (:func:`variant_rows`)."""
    return label.rpartition("-")[0] in labels


def block_teachers(source: Source, target: Path) -> str:
    """The results table of SAIL with every teacher (no variant): the paper's Table 2 axis. On the envs
    where a confirmed default has runs of its own label (:func:`default_envs`), these rows are the
    replaced default's, named so (:data:`REPLACED`)."""
    labels = {teacher for _, teacher, _ in source.groups}
    replaced = default_envs(source.groups, source.default_label)
    table = [
        {**row, "method": REPLACED + row["method"].removeprefix("sail")} if row["env"] in replaced else row
        for row in rows(source.groups)
        if method_name(row["method"]) == "sail" and not is_variant(row["teacher"], labels)
    ]
    return "\n".join(table_lines(table))


def block_variants(source: Source, target: Path) -> str:
    """Each variant beside its base (:func:`variant_table_lines`)."""
    return "\n".join(variant_table_lines(variant_rows(source.groups)))


COMPARED = ("sail", "dac")  # the seed-by-seed comparison of the paper's table: SAIL against the authors' DAC
# the methods whose README rows also show the best policy and the fall share beside last-5
MEASURED = ("sail", REPLACED, "dac")


def block_compared(source: Source, target: Path) -> str:
    """Per env, the last-5 mean of every seed of ``COMPARED``'s two methods with ``source.teacher`` at one
    budget (SAIL's default's runs, :attr:`Source.shown`), how many seeds of each end above every seed of
    the other, and Welch's t-test."""
    first, second = COMPARED
    groups = source.shown
    lines = [
        f"| env | teacher (return) | {first}: last-{HEADLINE_EVALS} (seed) | {second}: last-{HEADLINE_EVALS} (seed) "
        f"| {first} seeds above every {second} seed | {second} seeds above every {first} seed | Welch t | Welch p |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for env in readme_envs(groups, source.teacher):
        pairs = {}
        for group in pair_groups(groups, env, source.teacher):
            pairs.setdefault(total_frames(group.runs[0]), {})[method_name(group.method)] = group
        for _, methods in sorted(pairs.items(), key=lambda item: item[0] or 0):
            if first not in methods or second not in methods:
                continue
            ours, theirs = (sorted(methods[name].runs, key=lambda run: run.seed) for name in COMPARED)
            a, b = [run.headline_return for run in ours], [run.headline_return for run in theirs]
            t, p = welch(a, b)

            def seeds(runs: list[Run]) -> str:
                return ", ".join(f"{run.headline_return:.1f} ({run.seed})" for run in runs)

            lines.append(
                f"| {env} | {source.teacher} ({fmt(methods[first].teacher_return)}) | {seeds(ours)} | {seeds(theirs)} "
                f"| {sum(x > max(b) for x in a)}/{len(a)} | {sum(x > max(a) for x in b)}/{len(b)} | {fmt(t, 2)} "
                f"| {fmt(p, 3)} |"
            )
    return "\n".join(lines)


def kframes(frames: int | None) -> str:
    """``63500`` -> ``63.5k``; ``-`` for None."""
    return "-" if frames is None else f"{frames / 1000:g}k"


def logged(folder: Path, tags: tuple[str, ...]) -> dict[str, list[tuple[int, float]]]:
    """:func:`~torchrl_sail.harness.read_scalar` of several tags; a results copy's ``scalars.csv`` read once."""
    collected = folder / COLLECTED_SCALARS
    if not collected.is_file():
        return {tag: read_scalar(folder, tag) for tag in tags}
    out = {tag: [] for tag in tags}
    with collected.open(newline="") as file:
        for row in csv.DictReader(file):
            if row["tag"] in out:
                out[row["tag"]].append((int(float(row["frames"])), float(row["value"])))
    return out


def saturation(run: Run) -> tuple[str, str]:
    """The shares of a run's logged points with D saturated (accuracy at least
    :data:`~torchrl_sail.harness.D_SATURATED` on both sides) and with the actor saturated (at least
    :data:`~torchrl_sail.harness.ACTOR_SATURATED` of its action components at a bound), as ``summary.json``
    gives them (:func:`~torchrl_sail.harness.discriminator_summary`, :func:`~torchrl_sail.harness.actor_summary`),
    each with its last such frame; ``-`` where the run did not log it."""
    series = logged(run.folder, ("d/accuracy_teacher", "d/accuracy_agent", "actor/saturation"))
    agent = dict(series["d/accuracy_agent"])
    shares = (
        (
            series["d/accuracy_teacher"],
            lambda frame, value: value >= D_SATURATED and agent.get(frame, 0.0) >= D_SATURATED,
        ),
        (series["actor/saturation"], lambda frame, value: value >= ACTOR_SATURATED),
    )
    cells = []
    for points, saturated in shares:
        hits = [frame for frame, value in points if saturated(frame, value)]
        if not points:
            cells.append("-")
        elif not hits:
            cells.append("0%")
        else:
            share = 100 * len(hits) / len(points)
            cells.append(
                f"{share:.0f}% (last {kframes(hits[-1])})" if share >= 1 else f"{share:.1f}% (last {kframes(hits[-1])})"
            )
    return cells[0], cells[1]


def block_seeds(source: Source, target: Path) -> str:
    """One line per finished run: its last-5 mean, final and best evaluation, when it passed its teacher
    and its fall share since, its first promotion, promotions and final threshold C, and the shares of
    its logged points with D and with the actor saturated."""
    lines = [
        f"| run | teacher return | last-{HEADLINE_EVALS} | final | best | passed teacher at | fall share "
        "| first promotion | promoted | final C | D saturated | actor saturated |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for env, teacher in ordered_pairs(source.groups):
        for group in pair_groups(source.groups, env, teacher):
            for run in sorted(group.runs, key=lambda r: r.seed):
                summary, share = run.summary or {}, run.fall_share
                where = next(
                    (
                        run.folder.resolve().relative_to(root.resolve())
                        for root in source.roots
                        if inside(run.folder, root)
                    ),
                    run.folder,
                )
                d_saturated, actor_saturated = saturation(run)
                promoted = summary.get("num_promoted")
                threshold = summary.get("teacher_threshold")
                threshold = "-" if threshold is None else fmt(threshold, 0)
                fall = NA if share is None else fmt_fall(share["share"], share["falls"], share["evaluations"])
                lines.append(
                    f"| `{where}` | {fmt(run.teacher_return)} | {fmt(run.headline_return)} | {fmt(run.final_return)} "
                    f"| {fmt(run.best_return)} | {'offline' if run.offline else kframes(run.passed_teacher_at())} "
                    f"| {'offline' if run.offline else fall} | {kframes(summary.get('alpha_switched_at_frame'))} "
                    f"| {'-' if promoted is None else promoted} | {threshold} "
                    f"| {d_saturated} | {actor_saturated} |"
                )
    return "\n".join(lines)


def ant_runs(source: Source) -> dict:
    """The ant stage's runs of ``source``, read once for the two blocks made from them (``ant_rule.py``)."""
    return source.once("ant-runs", lambda: sibling("ant_rule").ant_runs(source.roots))


def block_trusted_rule(source: Source, target: Path) -> str:
    """The trusted-default decision rule applied to the runs (``trusted_rule.py``)."""
    return source.once("trusted-rule", lambda: sibling("trusted_rule").report(source.roots))


CAMPAIGN = Path("benchmarks/results/campaign")  # the results campaign's runs, relative to the repository
THROUGHPUT = Path("benchmarks/results/throughput")  # throughput.py's invocations
COLLECT = Path("benchmarks/results/collect")  # bench_collect.py's and bench_eval.py's records


def block_falls(source: Source, target: Path) -> str:
    """The actor against its target actor at the final checkpoint of campaign runs: each pair of
    ``examples/evaluate.py`` records ``<run>_online.json`` and ``<run>_target.json`` in
    ``source.roots[0]``, beside the run's own last evaluation (the run read under :data:`CAMPAIGN`)."""

    def returns(record: dict) -> str:
        lengths, mean = record["length"]["values"], record["dense_return"]["mean"]
        if min(lengths) == max(lengths):
            return f"{mean:.1f} (every episode {lengths[0]} steps)"
        low, high = min(lengths), max(lengths)
        longest = sum(length == high for length in lengths)
        return f"{mean:.1f} (episodes of {low}-{high} steps, {longest} of {len(lengths)} at {high})"

    lines = [
        "| run | frames | logged last evaluation | actor | target actor |",
        "|---|---|---|---|---|",
    ]
    found = []
    for online_file in sorted(source.roots[0].glob("*_online.json")):
        online = json.loads(online_file.read_text())
        target_file = online_file.with_name(online_file.name.removesuffix("_online.json") + "_target.json")
        target_record = json.loads(target_file.read_text())
        parts = Path(online["run_dir"]).parts  # ends <stage>/<teacher>/<env>/<method>/seed<n>, as in CAMPAIGN
        run = load_run(CAMPAIGN.joinpath(*parts[-5:]))
        found.append((run.final_return, parts[-5:], online, target_record))
    for final, parts, online, target_record in sorted(found, key=lambda item: item[0]):
        lines.append(
            f"| `{'/'.join(parts)}` | {kframes(online['checkpoint_frames'])} | {fmt(final)} | {returns(online)} "
            f"| {returns(target_record)} |"
        )
    return "\n".join(lines)


def block_random_policy(source: Source, target: Path) -> str:
    """A uniform random policy's return per env, from ``random_policy.py``'s JSON in ``source.roots[0]``."""
    random_policy = sibling("random_policy")
    data = json.loads((source.roots[0] / "random_policy.json").read_text())
    envs = data["envs"]
    return "\n".join(
        [
            random_policy.HEADER,
            *(random_policy.row(env, list(zip(e["returns"], e["lengths"], strict=True))) for env, e in envs.items()),
        ]
    )


def block_shipped_teachers(source: Source, target: Path) -> str:
    """The teachers shipped in ``source.roots[0]`` (``examples/teachers/<env>/``, from the ``metadata.json``
    that ``examples/make_teacher.py`` writes), in Table 1's env order, each beside the paper's teacher
    for its env on the gymnasium version the campaign runs the paper's teachers on (v4)."""
    shipped = {}
    for path in source.roots[0].glob("*/metadata.json"):
        meta = json.loads(path.read_text())
        if len(meta["episode_returns"]) != 1:
            raise ValueError(f"{path}: a shipped teacher is one episode, this has {len(meta['episode_returns'])}")
        shipped[meta["env_id"]] = meta
    lines = ["| env | return | steps | TD3 frames | the paper's teacher |", "|---|---|---|---|---|"]
    for env in sorted(shipped, key=table1_order):
        meta = shipped[env]
        (ret,), (steps,) = meta["episode_returns"], meta["episode_lengths"]
        paper = PAPER_TEACHER_RETURNS.get(paper_env(env)) if env.endswith("-v4") else None
        paper_cell = "-" if paper is None else f"{paper:.1f}"
        lines.append(f"| {env} | {ret:.1f} | {steps} | {meta['td3_frames'] // 1000}k | {paper_cell} |")
    return "\n".join(lines)


def comparison_cell(group: Group | None) -> str:
    """A cell of the paper's comparison: the last-5 mean ± std over seeds, then the best policy's."""
    if group is None:
        return "-"
    best = best_policy_cell(group.stats())
    return readme_cell(group) + ("" if best == "-" else f"; best policy {best}")


def comparison_rows(groups: dict, teacher: str, methods, names: dict, envs: list[str]) -> list[str]:
    """One row per method and budget with runs of ``teacher`` (the largest budget first: Table 1's
    1M), then, for a method of Table 1, the paper's row."""
    lines = []
    for method in methods:
        budgets = {}  # label -> one of its groups
        for (_, t, label), group in groups.items():
            if t == teacher and method_name(label) == method:
                budgets.setdefault(label, group)
        for label in reversed(sort_methods(budgets)):
            budget = frames_label(total_frames(budgets[label].runs[0]))
            cells = [comparison_cell(groups.get((env, teacher, label))) for env in envs]
            name = f"{names[method]} (`{method}`)" if method in names else f"`{method}`"
            lines.append(f"| {name}, {budget} frames | " + " | ".join(cells) + " |")
        if method in PAPER_TABLE1:
            paper = [PAPER_TABLE1[method].get(paper_env(env)) for env in envs]
            cells = ["-" if value is None else f"{value[0]} ± {value[1]}" for value in paper]
            lines.append(f"| {names.get(method, method)} in the paper, 1M frames | " + " | ".join(cells) + " |")
    return lines


def envs_with(groups: dict, teacher: str, methods, envs: list[str]) -> list[str]:
    """The envs of ``envs`` where one of ``methods`` has runs of ``teacher``."""
    return [env for env in envs if any((e, t) == (env, teacher) and method_name(m) in methods for e, t, m in groups)]


def table_header(envs: list[str]) -> list[str]:
    return ["| | " + " | ".join(paper_env(env) for env in envs) + " |", "|---" * (len(envs) + 1) + "|"]


# The paper's figures of curves that the comparison redraws: (file name, caption, methods), SAIL first
PAPER_FIGURES = (
    ("figure2", "Figure 2's methods", FIGURE2_ROWS),
    ("figures34", "Figures 3 and 4's variants of SAIL", FIGURE34_ROWS),
)


def paper_figure(source: Source, name: str) -> Path:
    """The PNG of one of :data:`PAPER_FIGURES` for ``source.teacher``."""
    return source.out / f"paper_{name}_{safe_name(source.teacher)}.png"


def paper_figure_envs(groups: dict, teacher: str, methods) -> list[str]:
    """The envs of a figure of :data:`PAPER_FIGURES`: where a method besides SAIL ran."""
    return envs_with(groups, teacher, methods[1:], readme_envs(groups, teacher))


def draw_paper_comparison(source: Source) -> None:
    """The curves of the paper's Figures 2-4 (:data:`PAPER_FIGURES`), one panel per env where they ran."""
    source.out.mkdir(parents=True, exist_ok=True)
    for name, _, methods in PAPER_FIGURES:
        envs = paper_figure_envs(source.shown, source.teacher, methods)
        if envs:
            plot_panels(paper_figure(source, name), source.teacher, envs, source.shown, methods)


def block_paper_comparison(source: Source, target: Path) -> str:
    """The paper's comparison laid out as the paper does: Table 1 (SAIL and its two exploration
    variants, beside the paper's figures), Figure 2's baselines and Figures 3-4's variants of SAIL
    (curves only in the paper: their tables, then their curves), each cell the last-5 mean ± std over
    seeds and the best policy's."""
    groups, teacher = source.shown, source.teacher
    envs = envs_with(groups, teacher, TABLE1_ROWS, readme_envs(groups, teacher))
    if not envs:
        raise ValueError(f"no finished run of SAIL or its variants with teacher {teacher!r} for {target}")
    teachers = [pair_groups(groups, env, teacher)[0].teacher_return for env in envs]
    sections = [
        f"**Table 1.** Per cell, the mean ± std over seeds of each run's last {HEADLINE_EVALS} evaluations, "
        "then of its best policy (the SAIL authors' rule); the paper's rows as it prints them (5 seeds, -v2 envs).",
        "",
        *table_header(envs),
        *comparison_rows(groups, teacher, TABLE1_ROWS, TABLE1_ROWS, envs),
        "| teacher | " + " | ".join(fmt(value) for value in teachers) + " |",
        "| teacher in the paper | "
        + " | ".join(fmt(PAPER_TEACHER_RETURNS.get(paper_env(env)), 2) for env in envs)
        + " |",
    ]
    for name, caption, methods in PAPER_FIGURES:
        shown = paper_figure_envs(groups, teacher, methods)
        if shown:
            rows_ = [
                line for line in comparison_rows(groups, teacher, methods, {}, shown) if "in the paper" not in line
            ]
            title = f"**{caption}** (the paper: curves only)."
            curves = figure_in(target, caption, paper_figure(source, name))
            sections += ["", title, "", *table_header(shown), *rows_, "", curves]
    return "\n".join(sections)


@dataclass(frozen=True)
class Block:
    """A generated block: ``render(source, target)`` makes its Markdown for the file ``target``;
    ``draw(source)``, if any, writes the figure it links."""

    render: Callable[[Source, Path], str]
    draw: Callable[[Source], None] | None = None


def throughput_block(*names: str) -> Block:
    """The table of ``throughput.py``'s invocations in the files ``names`` of the block's folder."""
    return Block(lambda source, target: sibling("throughput").docs_block([source.roots[0] / name for name in names]))


def collect_block(file: str, *labels: str, added: bool = False) -> Block:
    """The table of ``bench_collect.py``'s records ``labels`` in the file ``file`` of the block's folder."""
    return Block(
        lambda source, target: sibling("bench_collect").docs_table(source.roots[0] / file, list(labels), added)
    )


#: The collection records compared in the performance docs: a device-less env against one on the cpu
#: device (two invocations), and the exploration policy as one module against TorchRL's sequence
COLLECT_CHOICES = (
    "env on the cpu device (previous), invocation 1",
    "device-less env (current), invocation 1",
    "env on the cpu device (previous), invocation 2",
    "device-less env (current), invocation 2",
    "sequence policy (before)",
    "TD3ExplorationPolicy (after)",
)
FLOOR_RATIOS = [("EnvBase floor", "gymnasium"), ("GymEnv", "EnvBase floor")]

#: Every block ``--write-into FILE:BLOCK`` can write, by name.
BLOCKS = {
    "campaign-readme": Block(block_readme, draw_readme),
    "campaign": Block(block_teacher_table),
    "campaign-sail-vs-dac": Block(block_compared),
    "campaign-teachers": Block(block_teachers),
    "campaign-variants": Block(block_variants),
    "campaign-seeds": Block(block_seeds),
    "trusted-rule": Block(block_trusted_rule),
    "ant-rule": Block(lambda source, target: sibling("ant_rule").report_of(ant_runs(source))),
    "ant-choice": Block(lambda source, target: sibling("ant_rule").recommendation(ant_runs(source))),
    "hopper-falls": Block(block_falls),
    "random-policy": Block(block_random_policy),
    "shipped-teachers": Block(block_shipped_teachers),
    "paper-comparison": Block(block_paper_comparison, draw_paper_comparison),
    "throughput-amd-epyc": throughput_block("amd_epyc_fp32_flush.json"),
    "throughput-amd-epyc-no-flush": throughput_block("throughput.json"),
    "throughput-amd-epyc-avx512": throughput_block(
        "amd_epyc_avx512_fp32_flush.json", "amd_epyc_avx512_bf16_flush.json"
    ),
    "throughput-amx-xeon": throughput_block("amx_xeon_fp32_flush.json", "amx_xeon_bf16_flush.json"),
    "throughput-amx-xeon-no-flush": throughput_block("amx_xeon_fp32.json", "amx_xeon_bf16.json"),
    "throughput-cuda-h100": throughput_block(
        "cuda_h100_graphs.json", "cuda_h100_eager.json", "cuda_h100_graphs_bf16.json"
    ),
    "collect-choices": collect_block("collect.json", *COLLECT_CHOICES),
    "collect-per-transform": collect_block("collect.json", "per transform", added=True),
    "collect-floor": Block(
        lambda source, target: sibling("bench_collect").docs_ratios(
            source.roots[0] / "collect.json", "per transform, EnvBase floor", FLOOR_RATIOS
        )
    ),
    "collect-gpu": collect_block("gpu_h200.json", "H200 host, device=cuda", "H200 host, device=cpu"),
    "eval-ways": Block(
        lambda source, target: sibling("bench_eval").docs_table(source.roots[0] / "eval.json", "HalfCheetah, 1 thread")
    ),
}

#: The studies whose README tables ``study_tables.py`` makes from their runs (each table a block of the
#: name its ``tables.json`` gives it), relative to the repository
STUDIES = tuple(
    Path("benchmarks/results") / name
    for name in (
        "actor_saturation_cpu",
        "preact_h200",
        "precision_h200",
        "reward_form_h200",
        "reward_level_cpu",
        "reward_shift_h200",
        "rounding_cpu",
        "weak_swimmer_h200",
    )
)
#: Study tables of a docs page instead of a README: page -> the folder whose ``tables.json`` lists them
#: (their runs are the studies' folders, named relative to it)
STUDY_PAGES = {"docs/weak_teachers.md": Path("benchmarks/results/weak_teachers")}


def study_spec(study: Path) -> dict:
    """``study``'s ``tables.json``: its tables by name (``study_tables.py`` says what each holds)."""
    path = Path(study) / "tables.json"
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise ValueError(f"{path}: {err}") from err


def study_table_names(study: Path) -> list[str]:
    """The table names of ``study``'s ``tables.json``: each is a block of its README."""
    return list(study_spec(REPO / study))


def study_block(name: str) -> Block:
    return Block(lambda source, target: sibling("study_tables").render(source.roots[0], name))


STUDY_BLOCKS = {
    name: study_block(name) for study in (*STUDIES, *STUDY_PAGES.values()) for name in study_table_names(study)
}
if set(STUDY_BLOCKS) & set(BLOCKS):
    raise ValueError(f"study tables named as other blocks: {sorted(set(STUDY_BLOCKS) & set(BLOCKS))}")
BLOCKS.update(STUDY_BLOCKS)

#: The generated blocks of the repository's Markdown files: file -> {block: the folder it is made from}
#: (paths relative to the repository). ``--update-docs`` writes them, ``--check`` compares them.
DOCUMENTS = {
    "README.md": {"campaign-readme": CAMPAIGN},
    "docs/results.md": {
        "campaign": CAMPAIGN,
        "campaign-sail-vs-dac": CAMPAIGN,
        "paper-comparison": CAMPAIGN,
        "campaign-teachers": CAMPAIGN,
        "campaign-variants": CAMPAIGN,
        "hopper-falls": Path("benchmarks/results/hopper_falls"),
        "trusted-rule": CAMPAIGN,
        "ant-rule": CAMPAIGN,
    },
    "benchmarks/results/campaign/README.md": {"campaign-seeds": CAMPAIGN},
    "benchmarks/results/hopper_falls/README.md": {"hopper-falls": Path("benchmarks/results/hopper_falls")},
    "benchmarks/results/random_policy/README.md": {"random-policy": Path("benchmarks/results/random_policy")},
    "docs/training.md": {"shipped-teachers": Path("examples/teachers"), "ant-choice": CAMPAIGN},
    **{str(study / "README.md"): {name: study for name in study_table_names(study)} for study in STUDIES},
    **{page: {name: study for name in study_table_names(study)} for page, study in STUDY_PAGES.items()},
    "docs/performance.md": {
        **{
            name: THROUGHPUT
            for name in (
                "throughput-amd-epyc",
                "throughput-amd-epyc-no-flush",
                "throughput-amd-epyc-avx512",
                "throughput-amx-xeon",
                "throughput-amx-xeon-no-flush",
                "throughput-cuda-h100",
            )
        },
        **{
            name: COLLECT
            for name in ("collect-choices", "collect-per-transform", "collect-floor", "eval-ways", "collect-gpu")
        },
    },
}

# falls.py's tables: file -> (the run folders it reads, the teacher return of runs without a summary),
# paths relative to the repository
TUNING = Path("benchmarks/results/trusted_tuning")
# the average stage's (memory, seed) pairs (campaign.AVERAGE_SEEDS)
AVERAGE_RUNS = (("10k", 100), ("10k", 101), ("30k", 102), ("30k", 103))
FALLS = {
    "benchmarks/results/hopper_falls/falls_hopper_defaults.md": (
        [CAMPAIGN / f"main/paper/Hopper-v4/sail/seed{seed}" for seed in (0, 1, 2)]
        + [CAMPAIGN / "scale/paper/Hopper-v4/sail/seed0"],
        None,
    ),
    "benchmarks/results/hopper_falls/falls_walker2d_defaults.md": (
        [CAMPAIGN / f"main/paper/Walker2d-v4/sail/seed{seed}" for seed in (0, 1, 2)],
        None,
    ),
    "benchmarks/results/hopper_falls/falls_hopper_preact.md": (
        [CAMPAIGN / f"preact/paper-preact/Hopper-v4/sail/seed{seed}" for seed in (0, 1, 2)],
        None,
    ),
    "benchmarks/results/hopper_falls/falls_walker2d_preact.md": (
        [CAMPAIGN / f"preact/paper-preact/Walker2d-v4/sail/seed{seed}" for seed in (0, 1, 2)],
        None,
    ),
    # the three actors of the average stage's Hopper runs, and of the same runs with the teacher buffer held
    "benchmarks/results/remedies/falls_average_hopper.md": (
        [CAMPAIGN / f"average/paper-average{memory}/Hopper-v4/sail/seed{seed}" for memory, seed in AVERAGE_RUNS],
        None,
    ),
    "benchmarks/results/remedies/falls_average_walker2d.md": (
        [CAMPAIGN / f"average/shipped-average{memory}/Walker2d-v4/sail/seed{seed}" for memory, seed in AVERAGE_RUNS],
        None,
    ),
    "benchmarks/results/hold/falls.md": (
        [CAMPAIGN / f"hold/paper-average{memory}-hold/Hopper-v4/sail/seed{seed}" for memory, seed in AVERAGE_RUNS],
        None,
    ),
    # stopped runs, without a summary: their teachers' returns (the paper's Hopper one, the shipped Walker2d one)
    str(TUNING / "falls_hopper.md"): ([TUNING / "hop_paper_preact_s100"], 1480.688232421875),
    str(TUNING / "falls_walker2d.md"): ([TUNING / "walk_shipped_preact_s100"], 423.37884521484375),
}


def source_of(folder: Path, sources: dict[Path, Source]) -> Source:
    """The :class:`Source` of a folder of :data:`DOCUMENTS` (its report: ``<folder>/report``), read once."""
    if folder not in sources:
        # the campaign's SAIL default: the label of its runs with the paper's teachers (TABLE1_LABEL)
        default_label = sibling("campaign").TABLE1_LABEL if folder == CAMPAIGN else None
        sources[folder] = Source([folder], folder / "report", default_label=default_label)
    return sources[folder]


def generated_files(sources: dict[Path, Source]) -> dict[str, Callable[[], str]]:
    """The whole files made from committed runs, by path (relative to the repository): the campaign's
    report (``results.md``, ``results.csv``), the trusted-default rule, the averaged actor's
    confirmation (``averaged_rule.py``) and ``falls.py``'s tables
    (:data:`FALLS`, and the trusted-default runs' ``benchmarks/results/trusted/falls.md``)."""
    campaign = source_of(CAMPAIGN, sources)
    files = {
        str(CAMPAIGN / "report" / "results.md"): campaign.report,
        str(CAMPAIGN / "report" / "results.csv"): lambda: csv_text(rows(campaign.groups)),
        "benchmarks/results/trusted/rule.md": lambda: block_trusted_rule(campaign, Path("rule.md")) + "\n",
        "benchmarks/results/averaged/rule.md": lambda: sibling("averaged_rule").report(campaign.roots) + "\n",
    }
    for path, (folders, teacher_return) in FALLS.items():
        files[path] = lambda folders=folders, given=teacher_return: (
            sibling("falls").report(folders, 10_000, given) + "\n"
        )
    # the trusted-default runs that evaluated both actors where falls end episodes, as they come in
    files["benchmarks/results/trusted/falls.md"] = lambda: (
        sibling("falls").report(trusted_fall_runs(), 10_000, None) + "\n"
    )
    return files


def trusted_fall_runs() -> list[Path]:
    """The trusted-default candidate's committed Hopper and Walker2d runs, Hopper's first."""
    return [
        folder
        for env in ("Hopper-v4", "Walker2d-v4")
        for folder in sorted(CAMPAIGN.glob(f"trusted/*-trusted/{env}/sail/seed*"))
    ]


@contextlib.contextmanager
def in_folder(folder: Path):
    """Runs the body with ``folder`` as the working directory: the reports name runs relative to it."""
    before = Path.cwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(before)


def regenerate(text: str, where: Path, blocks: dict[str, Path], sources: dict[Path, Source]) -> tuple[str, list[str]]:
    """``text``, the file ``where`` (relative to the repository), with each of ``blocks`` made again from
    its folder, and the names of the blocks that changed. Runs in the repository's folder.

    Raises:
        ValueError: a block without its markers, or a block in ``text`` that ``blocks`` does not name.
    """
    unknown = sorted(set(block_names(text)) - set(blocks))
    if unknown:
        raise ValueError(f"{where} has generated blocks that aggregate.py does not make: {', '.join(unknown)}")
    changed = []
    for name, folder in blocks.items():
        new = replace_block(text, name, BLOCKS[name].render(source_of(folder, sources), where), where)
        if new != text:
            changed.append(name)
        text = new
    return text, changed


def read_exact(path: Path) -> str:
    """The text of ``path`` with its line endings as they are (``results.csv``'s are CSV's ``\\r\\n``)."""
    with open(path, newline="") as file:
        return file.read()


def update_docs(check: bool = False) -> list[str]:
    """Makes every generated block of :data:`DOCUMENTS` and every file of :func:`generated_files` again from
    the committed runs, and writes those that changed (with ``check``, writes nothing); also the
    figures they link. Returns what differed, one line each: ``<file>: block <name>``, or the file.
    """
    stale, sources = [], {}
    with in_folder(REPO):
        for name, folders in DOCUMENTS.items():
            path = Path(name)
            text = path.read_text()
            new, changed = regenerate(text, path, folders, sources)
            stale += [f"{name}: block {block}" for block in changed]
            if not check:
                for block, folder in folders.items():
                    if BLOCKS[block].draw is not None:
                        BLOCKS[block].draw(source_of(folder, sources))
                if changed:
                    write_atomic(path, new)
        for name, make in generated_files(sources).items():
            path, text = Path(name), make()
            if not path.is_file() or read_exact(path) != text:
                stale.append(name)
                if not check:
                    path.parent.mkdir(parents=True, exist_ok=True)  # a rule's folder, before its runs
                    write_atomic(path, text)
        if not check:
            source_of(CAMPAIGN, sources).draw_curves()
    return stale


def aggregate(
    roots: list[Path],
    out: Path,
    expect_methods: list[str] = (),
    expect_seeds: list[int] = (),
    per_run: bool = False,
    write_into: list[tuple[Path, str]] = (),
    teacher: str = "paper",
    default_label: str | None = None,
) -> str:
    """Reads the runs under ``roots``, writes the table, CSV and curves to ``out``; returns the Markdown
    (with ``per_run``, each finished run's :func:`run_details` after it). Also writes each
    ``(file, block)`` of ``write_into``: the block of :data:`BLOCKS` made from these runs, into the file.

    Raises:
        ValueError: a block name :data:`BLOCKS` does not have, or a file without the block's markers
            (checked before anything is written).
    """
    unknown = sorted({name for _, name in write_into} - set(BLOCKS))
    if unknown:
        raise ValueError(f"no generated block named {', '.join(unknown)}; the blocks: {', '.join(BLOCKS)}")
    for path, name in write_into:
        replace_block(Path(path).read_text(), name, "", path)  # the markers are there, before any work
    source = Source(roots, out, teacher, expect_methods, expect_seeds, default_label)
    source.draw_curves()
    write_atomic(out / "results.csv", csv_text(rows(source.groups)))
    text = source.report(per_run)
    write_atomic(out / "results.md", text)
    for path, name in write_into:
        block = BLOCKS[name]
        if block.draw is not None:
            block.draw(source)
        path = Path(path)
        write_atomic(path, replace_block(path.read_text(), name, block.render(source, path), path))
    return text


def block_target(value: str) -> tuple[Path, str]:
    """``FILE:BLOCK`` of ``--write-into``."""
    path, colon, name = value.rpartition(":")
    if not colon or not path or not name:
        raise argparse.ArgumentTypeError(f"expected FILE:BLOCK, got {value!r}")
    return Path(path), name


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("roots", nargs="*", type=Path, help="folders holding run folders (searched recursively)")
    parser.add_argument("--out", type=Path, help="where results.md, results.csv and the PNGs go")
    parser.add_argument("--expect-methods", nargs="+", default=[], help="list these methods as missing where absent")
    parser.add_argument(
        "--expect-seeds", nargs="+", type=int, default=[], help="list these seeds as missing where absent"
    )
    parser.add_argument("--per-run", action="store_true", help="add each finished run's own figures (a Runs section)")
    parser.add_argument(
        "--write-into",
        action="append",
        type=block_target,
        default=[],
        metavar="FILE:BLOCK",
        help=f"write a generated block between its markers in FILE (repeatable); blocks: {', '.join(BLOCKS)}",
    )
    parser.add_argument("--teacher", default="paper", help="the teacher label of the blocks that show one teacher")
    parser.add_argument(
        "--default-label",
        help="the teacher label of the default SAIL's runs with that teacher, where it is another: their rows "
        "are sail's, the --teacher label's sail rows the replaced default's",
    )
    modes = parser.add_mutually_exclusive_group()
    modes.add_argument(
        "--update-docs",
        action="store_true",
        help="write every generated block and file of the repository from the committed runs",
    )
    modes.add_argument(
        "--check", action="store_true", help="write nothing; exit 1 naming each generated block or file that differs"
    )
    args = parser.parse_args(argv)
    if args.update_docs or args.check:
        if args.roots or args.out or args.write_into:
            parser.error("--update-docs and --check read the committed runs: they take no roots, --out or --write-into")
    elif not args.roots or args.out is None:
        parser.error("give the folders of runs and --out (or --update-docs, --check)")
    return args


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    try:
        if args.update_docs or args.check:
            stale = update_docs(check=args.check)
            for line in stale:
                print(f"{line}: {'differs from the committed runs' if args.check else 'written'}")
            if args.check and stale:
                raise SystemExit(
                    f"aggregate.py: {len(stale)} generated block(s) or file(s) differ from the committed runs; "
                    "python benchmarks/aggregate.py --update-docs writes them"
                )
            return
        text = aggregate(
            args.roots,
            args.out,
            args.expect_methods,
            args.expect_seeds,
            args.per_run,
            write_into=args.write_into,
            teacher=args.teacher,
            default_label=args.default_label,
        )
        print(text, end="")
    except (FileNotFoundError, ValueError) as err:
        raise SystemExit(f"aggregate.py: {err}") from err


if __name__ == "__main__":
    main()
