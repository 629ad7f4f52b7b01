"""The results campaign: SAIL and the baselines on the paper's four envs, cell by cell, two runs at a time.

    python benchmarks/campaign.py --teachers-dir PATH/TO/teacher_dataset --out benchmarks/runs/campaign --jobs 2
    python benchmarks/campaign.py ... --stages main --dry-run     # print the commands, run nothing
    python benchmarks/campaign.py --out benchmarks/runs/campaign --collect benchmarks/results/campaign

Every run is ``examples/sail_td3.py`` with one torch thread, ``resume=auto`` (a stopped run
continues from its last checkpoint, a finished one is skipped), checkpoints every 25k frames
and deterministic evaluations of 10 episodes every 10k frames, in
``<out>/<stage>/<teacher>/<env>/<method>/seed<seed>`` (under each stage, the layout of
``run_matrix.py``), so ``aggregate.py <out>`` reads it. The queue is ordered so that the results table fills cell by
cell: seed 0 of every cell first, then the other seeds, then the 1M-frame runs, then the
teacher-quality and teacher-rule sweeps. ``--stages precision`` (never a default) pairs
``optim.precision=fp32`` and ``bf16`` on Hopper-v4, 100k frames, seeds 0-2; it needs bf16
hardware (AVX-512 or AMX, or a GPU with ``--overrides device=cuda``). ``--stages weak`` runs the
defaults with the weak teachers (the near-random Hopper one's seed 2: its seeds 0 and 1 are the
teachers stage's), ``--stages preact`` SAIL with the actor's pre-tanh penalty
(``optim.actor_preactivation_coef=0.001``; teacher labels ``<teacher>-preact``) on the weak and the
paper's teachers, ``--stages centred`` SAIL with its reward centred at D = 1/2
(``algo.reward.shift=-log 2``; teacher labels ``<teacher>-centred``), and ``--stages logit`` SAIL with
D's logit (``algo.reward.kind=airl``; ``<teacher>-logit``) on Swimmer and HalfCheetah, none a default.
``trusted``, the last default stage, is the trusted-default confirmation (the default's own rows of the
results table), ``--stages average`` tunes an averaged
actor (``eval.average_frames``) on tuning seeds 100-103, ``--stages hold`` reruns its Hopper runs
with the teacher buffer held after its first refill (``algo.max_promoted=10``, 200k frames; labels
``paper-average10k-hold``, ``paper-average30k-hold``), ``--stages remedies`` three remedies of the
falls with the candidate on the same seeds and teachers (``network.critic_layer_norm=true``,
``teacher.eviction=fifo``, ``optim.actor_lr=0.0003``; labels ``<teacher>-trusted-ln``, ``-fifo``,
``-actor_lr``), ``--stages averaged`` the averaged actor's confirmation (the trusted stage's candidate
runs again with ``eval.actor=average`` at :data:`AVERAGED_MEMORY`; labels ``<teacher>-averaged``; not
the ``average`` stage, which tuned it); after the trusted-default confirmation,
with the default it decided (:data:`AFTER_TRUSTED`),
``ant`` runs SAIL and DAC on Ant-v4 with the authors' Ant teacher as recorded (label ``paper``)
and on the columns Ant-v4 reproduces (``paper-nocontact``), ``comparison`` the paper's other rows
and ``table1`` SAIL at 1M frames (seeds 0-2 each; under the label of the default's runs,
``TABLE1_LABEL``, ``paper-trusted``), none a default. The SAIL cells of the stages before it
name SAIL's replaced default (:data:`REPLACED_DEFAULTS`), so that their commands reproduce their runs.
``--envs`` and ``--seeds`` keep only those cells of the stages (``--stages weak preact --seeds 0``
pairs each "before" seed with its "after" sooner), and ``--methods`` keeps only those methods' cells.
``--jobs`` runs go at once; rerunning the same command after an interruption continues where it
stopped, the started runs first (:func:`started_first`).
``--teachers-dir`` holds the SAIL authors' teacher files
(``expert_data_no_img_<Env>_scores_<score>_episodes_1.npz``; ``python -m torchrl_sail.data.download``
fetches them, Ant's included).

``--collect DEST`` copies what the report needs of every finished run under ``--out`` to the
same place under ``DEST`` (``aggregate.py DEST`` reads it): ``config.yaml``, ``summary.json``,
the stage's ``matrix.json``, and one ``scalars.csv`` (``tag,frames,value``) with the evaluation
curve and the diagnostics of :data:`DIAGNOSTICS`, not the per-scalar log folders (a run folder
without logs, a results copy put back under ``--out`` to mark its cell done, gives its own
``scalars.csv`` unchanged). With
``--collect``, ``--stages``, ``--envs`` and ``--seeds`` keep only those runs (``--collect DEST
--stages scale --envs Hopper-v4`` copies the one 1M-frame Hopper run).

``--status`` prints, for the stages asked (``--envs`` and ``--seeds`` too), how many runs under
``--out`` are done, started (a checkpoint saved, which ``resume=auto`` continues from) and not
started, per teacher label and method, then each started run's checkpoint frame and last evaluation,
and the frames left with about how long ``--jobs`` runs at a time take to train them.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import shlex
import shutil
import statistics
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run_matrix import REPO, Teacher, learners, record_matrix, script_for  # noqa: E402

from torchrl_sail.harness import checkpoint_frames, native_bf16_matmul, read_scalar  # noqa: E402

# The authors' one-trajectory teachers (their settings.py optimal_score names the file).
PAPER_TEACHERS = {
    "Hopper-v4": "expert_data_no_img_Hopper_scores_1500_episodes_1.npz",
    "HalfCheetah-v4": "expert_data_no_img_HalfCheetah_scores_5600_episodes_1.npz",
    "Walker2d-v4": "expert_data_no_img_Walker2d_scores_1500_episodes_1.npz",
    "Swimmer-v4": "expert_data_no_img_Swimmer_scores_120_episodes_1.npz",
}
ENVS = list(PAPER_TEACHERS)
# The teachers the authors published beside the paper's, for the envs of the ant stage: Ant-v2's 111
# columns, whose 84 contact-force columns (27-110) mujoco-py 2.x recorded as 0.0 where Ant-v4 fills them
OTHER_TEACHERS = {"Ant-v4": "expert_data_no_img_Ant_scores_1200_episodes_1.npz"}
TEACHER_FILES = {**PAPER_TEACHERS, **OTHER_TEACHERS}
# The Ant teacher on the 27 columns Ant-v4 reproduces, and the time feature (label "paper-nocontact")
ANT_OWN_COLUMNS = ("env.kwargs.use_contact_forces=false", "teacher.drop_columns=27-110")
# The weak-teacher study's teachers (make_teacher.py; benchmarks/README.md has how each was made),
# folders under --weak-teachers-dir, one per env, each its own label. The third, Hopper's near-random
# teacher, is --random-teacher (label "random", as in the teachers stage).
WEAK_TEACHERS = {
    "Swimmer-v4": "weak_swimmer",
    "HalfCheetah-v4": "early_halfcheetah",
}
# -log(1 - D) - log 2: SAIL's reward minus its value at D = 1/2, so negative on the rows D calls the agent's
CENTRED = (f"algo.reward.shift={-math.log(2)}",)
# rlkit's pre-tanh penalty on the actor: keeps its tanh out of the saturation a stalled run sits in
PREACT = ("optim.actor_preactivation_coef=0.001",)
# The trusted-default candidate (docs/results.md, "The trusted default: decision rule"): the pre-tanh
# penalty against stalls, and the target actor (the Polyak average of the actor's recent weights)
# evaluated, kept as the best policy and shipped, against falls. Every run also evaluates the online
# actor (eval/return_online): the falls' evidence, paired.
TRUSTED = ("optim.actor_preactivation_coef=0.001", "eval.actor=target", "eval.other_actor=true")
# the trusted-default confirmation: the paper's teachers and the shipped ones, seeds 0-4
TRUSTED_SEEDS = (0, 1, 2, 3, 4)
# the riskiest first: the teachers that stalled, then those that fell
TRUSTED_ORDER = (
    ("Swimmer-v4", "shipped"),
    ("HalfCheetah-v4", "paper"),
    ("Walker2d-v4", "shipped"),
    ("Hopper-v4", "paper"),
    ("Walker2d-v4", "paper"),
    ("HalfCheetah-v4", "shipped"),
    ("Swimmer-v4", "paper"),
    ("Hopper-v4", "shipped"),
)
# The averaged actor's tuning, on tuning seeds (>= 100): the candidate's training where its runs fell
# most (Hopper, the paper's teacher) and where a new user's first run fell (Walker2d, the shipped
# teacher), each run also evaluating an average of the actor's weights over one memory
# (eval.average_frames; eval.other_actor=true puts all three actors on the same start states).
# Training does not depend on the memory, so each memory has seeds of its own rather than rerunning
# the other's training: labels "<teacher>-average<memory>k".
AVERAGE_SEEDS = {10_000: (100, 101), 30_000: (102, 103)}
AVERAGE_TEACHERS = (("Hopper-v4", "paper"), ("Walker2d-v4", "shipped"))
# Three remedies of the falls, each added to the candidate, tuned on the average stage's seeds and
# teachers, so that its runs (the candidate's training on the same seeds) are their baseline: the
# critic's LayerNorm (RLPD), the SAIL authors' FIFO teacher ring at their capacities (on Hopper,
# 1e5 transitions, whose teacher data changes by a smaller share at each promotion than the top-K
# buffer's: falls came more often after the threshold's largest rises early in a run, a tendency,
# benchmarks/results/hopper_falls/README.md; on Walker2d, 1e4, about the top-K buffer's size, with
# the oldest rows evicted, not the worst), and the actor's learning rate at 3e-4 (the online actor's
# falls follow TD3 blocks that moved it somewhat further than usual, benchmarks/results/trusted/falls.md,
# a small effect and not seen before the target actor's).
# Labels "<teacher>-trusted-<remedy>".
REMEDIES = {
    "ln": ("network.critic_layer_norm=true",),
    "fifo": ("teacher.eviction=fifo",),
    "actor_lr": ("optim.actor_lr=0.0003",),
}
REMEDY_SEEDS = (100, 101, 102, 103)
# The averaged actor's confirmation (docs/results.md, "What a fall on Hopper is"): the trusted stage's
# 40 candidate runs again, their averaged actor, at the memory the average stage chose
# (benchmarks/results/remedies/rule.md), evaluated, kept and shipped, and the target and online actors
# evaluated beside it on the same start states. Training is the candidate's. Labels "<teacher>-averaged".
AVERAGED_MEMORY = 10_000
AVERAGED = (
    *(item.replace("eval.actor=target", "eval.actor=average") for item in TRUSTED),
    f"eval.average_frames={AVERAGED_MEMORY}",
)
# Whether the teacher buffer's change causes the falls: the average stage's Hopper runs again, with
# promotions stopped at the teacher buffer's first refill (algo.max_promoted = K = 10: with the
# paper's one-episode teacher, C first rises when the tenth agent trajectory evicts the
# demonstration), so that C and the teacher data hold from there while the average stage's runs go
# on raising them. On one commit and machine, both train alike until the held run's pair promotes
# more (benchmarks/hold_rule.py checks it); 200k frames, where the falls came. Labels
# "<average stage's label>-hold".
HOLD = ("algo.max_promoted=10",)
HOLD_FRAMES = 200_000
# The paper's whole comparison with its teachers, seeds 0-2 (its own scale): Table 1's exploration
# variants (Curiosity, Entropy) and Figure 2's baselines on the four envs, Figure 3's on-policy D and
# Figure 4's ablations on Hopper and HalfCheetah, at 300k frames; SAIL at Table 1's 1M frames.
# dac_published: not the paper's, but the published table's row, rerun on the release's loop
COMPARISON_METHODS = ("sail_rnd", "sail_sac", "gail", "pofd", "ddpgfd", "dac_published")
ABLATIONS = ("sail_onpolicy", "sail_no_lfd", "sail_no_adapt")
ABLATION_ENVS = ("Hopper-v4", "HalfCheetah-v4")
COMPARISON_SEEDS = (0, 1, 2)
# SAIL at Table 1's 1M frames runs under the teacher label of the default's own paper-teacher runs: the
# trusted stage's ("paper-trusted"), whose candidate is the default; with "paper" (the replaced
# default's) it would leave out the scale stage's 1M-frame cells (the same runs)
TABLE1_LABEL = "paper-trusted"
# Table 1's runs also evaluate the actor training beside the target actor they ship, as the trusted
# stage's runs did, so that each actor's falls at 1M frames are read on the same runs
TABLE1_OVERRIDES = ("eval.other_actor=true",)
# The stages that run with the default the trusted-default confirmation decided; every other stage ran
# before it, with SAIL's replaced default (REPLACED_DEFAULTS), which its cells name (with_replaced_defaults)
AFTER_TRUSTED = ("ant", "comparison", "table1")
# SAIL's settings before the confirmation made its candidate the default (conf/algo/sail.yaml), for the
# methods whose files extend sail.yaml (the SAIL variants on TD3)
REPLACED_DEFAULTS = ("optim.actor_preactivation_coef=0.0", "eval.actor=online")
SAIL_FAMILY = ("sail", "sail_no_adapt", "sail_no_lfd", "sail_onpolicy", "sail_rnd")
# the stages that run SAIL on the weak teachers (a teacher label "<weak teacher>[-<stage>]")
WEAK_STAGES = ("weak", "preact", "centred", "logit")
# D's logit log D - log(1 - D), negative on agent rows: it can pay a fall, so only where no fall ends an episode
LOGIT = ("algo.reward.kind=airl",)
NO_EARLY_TERMINATION = ("Swimmer-v4", "HalfCheetah-v4")
WEAK_TEACHERS_DIR = REPO / "benchmarks" / "results" / "campaign" / "teachers"
# What a run's report needs from its logs: the evaluation curve (with the share of each evaluation's
# episodes below the teacher, and its lowest episode), then the diagnostics that explain it (D's
# accuracy and rewards on both sides, Q, the actor's saturation, the threshold C and promotions,
# alpha, speed).
DIAGNOSTICS = (
    "eval/return",
    "eval/return_target",
    "eval/return_online",
    "eval/below_teacher",
    "eval/below_teacher_target",
    "eval/below_teacher_online",
    "eval/min_return",
    "eval/min_return_target",
    "eval/min_return_online",
    "eval/return_average",
    "eval/below_teacher_average",
    "eval/min_return_average",
    "actor/change",
    "actor/target_gap",
    "train/dense_return",
    "teacher/threshold",
    "teacher/num_promoted",
    "alpha",
    "d/accuracy_teacher",
    "d/accuracy_agent",
    "d/reward_teacher",
    "d/reward_agent",
    "d/reward_teacher_std",
    "d/reward_agent_std",
    "d/logit_teacher",
    "d/logit_agent",
    "d/logit_teacher_std",
    "d/logit_agent_std",
    "d/grad_penalty",
    "d/skipped",
    "sail/q_mean",
    "sail/loss_qvalue",
    "sail/d_reward_mean",
    "sail/env_reward_mean",
    "sail/preactivation_penalty",
    "actor/saturation",
    "actor/preactivation",
    "time/fps",
    # each comparison method's own
    "train/intrinsic_reward",
    "rnd/loss_predictor",
    "sail/temperature",
    "sail/entropy",
    "sail/teacher_share",
    "sail/priority_weight_mean",
    "sail/actor_lr",
    "ppo/loss_objective",
    "ppo/loss_critic",
    "ppo/entropy",
    "ppo/lr",
    "pofd/lambda_1",
)
# what runs without --stages (the others are never defaults)
DEFAULT_STAGES = ("main", "scale", "teachers", "buffer", "trusted")
COMMON = (
    "threads=1",
    "resume=auto",
    "logger.backends=[csv]",
    "eval.episodes=10",
    "eval.every_frames=10000",
    "checkpoint.every_frames=25000",
)


@dataclass(frozen=True)
class Cell:
    """One run: a method on an env with a teacher and a seed, for a budget."""

    stage: str
    env: str
    method: str
    seed: int
    frames: int
    teacher: str = "paper"  # the label: a folder under --out
    overrides: tuple[str, ...] = ()


def plan() -> list[Cell]:
    """The campaign's runs in the order they go."""
    cells = []
    for env in ENVS:  # seed 0 of every cell of the main table first
        cells += [Cell("main", env, method, 0, 300_000) for method in ("sail", "dac")]
    for env in ENVS:
        cells += [Cell("main", env, "bc", seed, 300_000) for seed in (0, 1, 2)]  # offline: seconds each
        cells += [Cell("main", env, method, 0, 300_000) for method in ("td3_delayed", "dac_published")]
    for seed in (1, 2):
        for env in ENVS:
            cells += [Cell("main", env, method, seed, 300_000) for method in ("sail", "dac")]
    cells += [Cell("scale", env, "sail", 0, 1_000_000) for env in ("HalfCheetah-v4", "Hopper-v4")]
    for seed in (0, 1):  # the teacher-quality sweep (the paper's Table 2) and the teacher-buffer rule
        cells += [
            Cell("teachers", "Hopper-v4", "sail", seed, 300_000, teacher=label) for label in ("random", "shipped")
        ]
        cells += [
            Cell(
                "buffer",
                "Hopper-v4",
                "sail",
                seed,
                300_000,
                teacher=f"paper-{rule}",
                overrides=(f"teacher.eviction={rule}",),
            )
            for rule in ("fifo", "union")
        ]
    # The defaults with weak teachers, 3 seeds (the weak-teacher study's "before" rows): not in the
    # default stages, as they come after the main table. The near-random Hopper teacher's seeds 0 and 1
    # are the teachers stage's "random" cells; its seed 2 joins them under the same label.
    cells += [
        Cell("weak", env, "sail", seed, 300_000, teacher=label)
        for seed in (0, 1, 2)
        for env, label in WEAK_TEACHERS.items()
    ]
    cells.append(Cell("weak", "Hopper-v4", "sail", 2, 300_000, teacher="random"))
    # fp32 against bf16 (optim.precision), seed by seed, so each pair runs side by side: not in the
    # default stages, as bf16 needs bf16 hardware (--stages precision, on AVX-512/AMX or a GPU)
    cells += [
        Cell(
            "precision",
            "Hopper-v4",
            "sail",
            seed,
            100_000,
            teacher=f"paper-{precision}",
            overrides=(f"optim.precision={precision}",),
        )
        for seed in (0, 1, 2)
        for precision in ("fp32", "bf16")
    ]
    # The weak-teacher study's candidate remedies, each its own rows ("<teacher>-<stage>") beside the
    # defaults': the weak teachers, then the paper's, seed by seed. Not in the default stages, as they
    # come after the main table. preact: the actor's pre-tanh penalty (rlkit's); centred: SAIL's reward
    # centred at D = 1/2 (ours); logit: D's logit, only where no fall ends an episode (ours).
    for stage, overrides, paper_envs in (
        ("preact", PREACT, ENVS),
        ("centred", CENTRED, ENVS),
        ("logit", LOGIT, NO_EARLY_TERMINATION),
    ):
        for seed in (0, 1, 2):
            cells += [
                Cell(stage, env, "sail", seed, 300_000, f"{label}-{stage}", overrides)
                for env, label in (*WEAK_TEACHERS.items(), ("Hopper-v4", "random"))
                if env in paper_envs
            ]
            cells += [Cell(stage, env, "sail", seed, 300_000, f"paper-{stage}", overrides) for env in paper_envs]
    # The trusted-default confirmation, seed by seed: the candidate on the 8 teachers ("<teacher>-trusted"),
    # then what its decision rule compares it with, under the labels of the rows they complete: the
    # defaults on the shipped teachers ("shipped", the teachers stage's Hopper seeds 0-1 done), and the
    # defaults and DAC with the paper's teachers, seeds 3-4 ("paper", the main table's seeds 0-2 done).
    for seed in TRUSTED_SEEDS:
        cells += [
            Cell("trusted", env, "sail", seed, 300_000, f"{label}-trusted", TRUSTED) for env, label in TRUSTED_ORDER
        ]
        cells += [
            Cell("trusted", env, "sail", seed, 300_000, "shipped")
            for env, label in TRUSTED_ORDER
            if label == "shipped" and not (env == "Hopper-v4" and seed in (0, 1))
        ]
        if seed >= 3:
            cells += [Cell("trusted", env, method, seed, 300_000) for env in ENVS for method in ("sail", "dac")]
    for pair in zip(*AVERAGE_SEEDS.values(), strict=True):  # one seed of each memory at a time
        cells += [
            Cell(
                "average",
                env,
                "sail",
                seed,
                300_000,
                f"{label}-average{memory // 1000}k",
                (*TRUSTED, f"eval.average_frames={memory}"),
            )
            for memory, seed in zip(AVERAGE_SEEDS, pair, strict=True)
            for env, label in AVERAGE_TEACHERS
        ]
    cells += [
        Cell("hold", c.env, c.method, c.seed, HOLD_FRAMES, f"{c.teacher}-hold", (*c.overrides, *HOLD))
        for c in cells
        if c.stage == "average" and c.env == "Hopper-v4"
    ]
    for seed in TRUSTED_SEEDS:
        cells += [
            Cell("averaged", env, "sail", seed, 300_000, f"{label}-averaged", AVERAGED) for env, label in TRUSTED_ORDER
        ]
    for seed in REMEDY_SEEDS:
        cells += [
            Cell("remedies", env, "sail", seed, 300_000, f"{label}-trusted-{name}", (*TRUSTED, *overrides))
            for name, overrides in REMEDIES.items()
            for env, label in AVERAGE_TEACHERS
        ]
    # Beyond the paper's four envs, after the trusted default is decided (its SAIL rows use the default
    # of the commit they run from): SAIL and DAC on Ant-v4 with the authors' teacher as recorded
    # ("paper": 111 columns, the contact forces on) and on the columns Ant-v4 reproduces
    # ("paper-nocontact"), seed by seed.
    for seed in COMPARISON_SEEDS:
        cells += [
            Cell("ant", "Ant-v4", method, seed, 300_000, teacher, overrides)
            for teacher, overrides in (("paper", ()), ("paper-nocontact", ANT_OWN_COLUMNS))
            for method in ("sail", "dac")
        ]
    # The paper's comparison, after the trusted default is decided (its SAIL rows use the default of
    # the commit they run from): the 300k rows seed by seed, then Table 1 at 1M. It runs no SAIL 300k
    # row of its own: the variants compare with the trusted stage's paper-teacher runs of the default
    # (TABLE1_LABEL's, which aggregate.py shows as sail's).
    for seed in COMPARISON_SEEDS:
        cells += [Cell("comparison", env, method, seed, 300_000) for env in ENVS for method in COMPARISON_METHODS]
        cells += [Cell("comparison", env, method, seed, 300_000) for env in ABLATION_ENVS for method in ABLATIONS]
    scale = {(c.env, c.seed) for c in cells if c.stage == "scale"}
    cells += [
        Cell("table1", env, "sail", seed, 1_000_000, TABLE1_LABEL, TABLE1_OVERRIDES)
        for seed in COMPARISON_SEEDS
        for env in ENVS
        if TABLE1_LABEL != "paper" or (env, seed) not in scale
    ]
    return [with_replaced_defaults(cell) for cell in cells]


def with_replaced_defaults(cell: Cell) -> Cell:
    """``cell`` as it ran: a SAIL cell of a stage before the trusted default (not in :data:`AFTER_TRUSTED`)
    with SAIL's replaced default (:data:`REPLACED_DEFAULTS`) before its own overrides, each setting its
    overrides leave alone, so that its command reproduces its runs from this commit."""
    if cell.stage in AFTER_TRUSTED or cell.method not in SAIL_FAMILY:
        return cell
    own = {item.split("=", 1)[0] for item in cell.overrides}
    replaced = tuple(item for item in REPLACED_DEFAULTS if item.split("=", 1)[0] not in own)
    return replace(cell, overrides=(*replaced, *cell.overrides))


def device_of(overrides: list[str]) -> str:
    """The torch device that ``--overrides`` give the runs (the example's default: ``cpu``)."""
    devices = [item.split("=", 1)[1] for item in overrides if item.lstrip("+").startswith("device=")]
    return devices[-1] if devices else "cpu"


def teacher_path(
    cell: Cell, teachers_dir: Path | None, random_teacher: Path | None, weak_dir: Path = WEAK_TEACHERS_DIR
) -> Path | None:
    label = base_label(cell)
    if label.startswith("paper"):
        return teachers_dir / TEACHER_FILES[cell.env]
    if label == "random":
        return random_teacher
    if cell.stage in WEAK_STAGES:
        return weak_dir / label
    return None  # "shipped": the teacher shipped for the env (examples/teachers)


def base_label(cell: Cell) -> str:
    """The cell's teacher label without its remedy stage's suffix: ``random-preact`` is ``random``."""
    return cell.teacher.removesuffix(f"-{cell.stage}")


def run_dir_of(cell: Cell, out: Path) -> Path:
    """The cell's run folder under ``out``: ``<stage>/<teacher>/<env>/<method>/seed<seed>``."""
    return out / cell.stage / cell.teacher / cell.env / cell.method / f"seed{cell.seed}"


def command(
    cell: Cell, out: Path, teacher: Path | None, python: str = sys.executable, extra: tuple[str, ...] = ()
) -> list[str]:
    """The run's command: the training script of the method's family (``sail_td3.py``, ``gail.py``, ``bc.py``),
    with the cell's overrides, then ``extra`` (``--overrides``)."""
    run_dir = run_dir_of(cell, out)
    return [
        python,
        str(script_for(cell.method)),
        f"algo={cell.method}",
        f"env={cell.env}",
        f"seed={cell.seed}",
        f"collector.total_frames={cell.frames}",
        *COMMON,
        *([f"teacher.path={teacher}"] if teacher is not None else []),
        *cell.overrides,
        *extra,
        f"hydra.run.dir={run_dir}",
    ]


def finished(run_dir: Path) -> bool:
    """A run whose ``summary.json`` reports its whole budget done."""
    summary = run_dir / "summary.json"
    if not summary.exists():
        return False
    done = json.loads(summary.read_text())
    return done.get("offline", False) or done.get("frames", 0) >= done.get("total_frames", 1)


def status(cells: list[Cell], out: Path, jobs: int = 2) -> list[str]:
    """Where ``cells`` stand under ``out``, as report lines: per stage, then per teacher label and
    method, how many runs are done (their whole budget, :func:`finished`), started (a checkpoint
    saved; ``resume=auto`` continues from it) and not started; then each started run with its
    checkpoint's frame and its last evaluation; then the frames left and, timed by the finished runs
    that trained in one start, about how long ``jobs`` runs at a time take to train them
    (:func:`time_left`)."""
    groups: dict[tuple, list[str]] = {}
    started, left, paces = [], [], []
    for cell in cells:
        run_dir = run_dir_of(cell, out)
        if finished(run_dir):
            state, frames = "done", None
            summary = json.loads((run_dir / "summary.json").read_text())
            # a resumed run's frames_per_second times its last start alone, perhaps short or on another machine
            if len(summary.get("starts", [])) == 1:
                paces.append(summary.get("frames_per_second"))
        else:
            frames = checkpoint_frames(run_dir)
            state = "not started" if frames is None else "started"
            if learners()[cell.method] != "bc":  # BC trains on the demonstrations alone: no frames, seconds
                left.append(cell.frames - (frames or 0))
        groups.setdefault((cell.stage,), []).append(state)
        groups.setdefault((cell.stage, cell.teacher, cell.method), []).append(state)
        if state == "started":
            evaluations = read_scalar(run_dir, "eval/return")
            last = f", evaluated {evaluations[-1][1]:.1f} at {evaluations[-1][0]}" if evaluations else ""
            started.append(f"  {run_dir.relative_to(out)}: checkpoint at {frames} of {cell.frames} frames{last}")
    lines = []
    for key, states in groups.items():
        counts = ", ".join(f"{states.count(s)} {s}" for s in ("done", "started", "not started") if s in states)
        name = key[0] if len(key) == 1 else f"  {key[1]} {key[2]}"
        lines.append(f"{name}: {len(states)} runs, {counts}")
    if started:
        lines += ["started (resume=auto continues each from its checkpoint):", *started]
    return lines + time_left(left, [pace for pace in paces if pace], jobs)


def started_first(cells: list[Cell], out: Path) -> list[Cell]:
    """``cells`` with the started ones (a checkpoint saved, not finished) first, each part in its
    order: a queue restarted on a machine that kept its run folders finishes what it began before it
    starts anything new, so less is lost if the next restart is on a fresh machine."""

    def began(cell: Cell) -> bool:
        run_dir = run_dir_of(cell, out)
        try:
            return not finished(run_dir) and checkpoint_frames(run_dir) is not None
        except ValueError:  # an unreadable checkpoint: its run says so when its turn comes, not the queue
            return False

    return sorted(cells, key=lambda cell: not began(cell))  # a stable sort keeps each part's order


def time_left(left: list[int], paces: list[float], jobs: int) -> list[str]:
    """The frames ``left`` (one entry per unfinished run that collects frames) and, at the median of
    ``paces`` (finished runs' frames per second, each run on its own) with ``jobs`` runs at a time (at
    most as many as are left), about how many hours they take: the frames over that many runs' pace,
    and never less than the longest run alone. A run that starts over (a new machine) adds to it."""
    if not left:
        return []
    line = f"left: {sum(left)} frames in {len(left)} runs"
    if not paces:
        return [line + " (no finished run here records a single start and its frames_per_second)"]
    pace, at_once = statistics.median(paces), min(jobs, len(left))
    hours = max(sum(left) / (pace * at_once), max(left) / pace) / 3600
    return [
        f"{line}; about {hours:.1f} h at {at_once} run{'s' if at_once > 1 else ''} at a time, each at "
        f"{pace:.1f} frames/s (the median frames_per_second of the {len(paces)} "
        f"run{'s' if len(paces) > 1 else ''} here that finished in one start)"
    ]


def collect(
    out: Path,
    dest: Path,
    stages: list[str] | None = None,
    envs: list[str] | None = None,
    seeds: list[int] | None = None,
    methods: list[str] | None = None,
) -> list[Path]:
    """Copies the report's files of every finished run under ``out`` to ``dest``; returns the runs copied.

    ``stages``, ``envs``, ``seeds`` and ``methods`` (each ``None`` for all) keep only the runs whose
    folder, ``<stage>/<teacher>/<env>/<method>/seed<seed>``, names them.
    """
    seed_folders = None if seeds is None else {f"seed{seed}" for seed in seeds}
    runs = []
    for summary in sorted(out.glob("*/*/*/*/*/summary.json")):
        run_dir = summary.parent
        stage, _, env, method, seed = run_dir.relative_to(out).parts
        if (
            (stages is None or stage in stages)
            and (envs is None or env in envs)
            and (methods is None or method in methods)
            and (seed_folders is None or seed in seed_folders)
            and finished(run_dir)
        ):
            runs.append(run_dir)
    for run_dir in runs:  # checked before anything is copied
        if not (run_dir / "config.yaml").exists():
            raise FileNotFoundError(f"{run_dir} has a summary.json but no config.yaml: not a run folder")
        if not (run_dir / "logs" / "scalars").is_dir() and not (run_dir / "scalars.csv").exists():
            # an empty scalars.csv would replace the curve of the results copy it came from
            raise FileNotFoundError(f"{run_dir} has neither logs/scalars nor a scalars.csv: nothing to collect")
    copied = []
    for run_dir in runs:
        target = dest / run_dir.relative_to(out)
        target.mkdir(parents=True, exist_ok=True)
        for name in ("config.yaml", "summary.json"):
            shutil.copy2(run_dir / name, target / name)
        stage = run_dir.relative_to(out).parts[0]
        if (out / stage / "matrix.json").exists():
            shutil.copy2(out / stage / "matrix.json", dest / stage / "matrix.json")
        if (run_dir / "logs" / "scalars").is_dir():
            with open(target / "scalars.csv", "w", newline="") as file:
                writer = csv.writer(file)
                writer.writerow(["tag", "frames", "value"])
                for tag in DIAGNOSTICS:
                    path = run_dir / "logs" / "scalars" / f"{tag}.csv"
                    if path.exists():
                        writer.writerows([tag, *line.split(",")] for line in path.read_text().split())
        else:  # a results copy put back under --out: kept as it is
            shutil.copy2(run_dir / "scalars.csv", target / "scalars.csv")
        copied.append(target)
    return copied


def runs_at_a_time(text: str) -> int:
    """``--jobs``: a whole number, at least 1."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: at least 1 run at a time")
    return int(text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--teachers-dir", type=Path, help="the authors' teacher_dataset folder")
    parser.add_argument(
        "--random-teacher",
        type=Path,
        help="a near-random Hopper-v4 teacher (examples/make_teacher.py); without it every stage skips its "
        "'random' cells",
    )
    parser.add_argument(
        "--weak-teachers-dir",
        type=Path,
        default=WEAK_TEACHERS_DIR,
        help=f"the weak teachers of --stages weak: {', '.join(WEAK_TEACHERS.values())} (default: %(default)s)",
    )
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument(
        "--stages",
        nargs="+",
        choices=[
            "main",
            "scale",
            "teachers",
            "buffer",
            "weak",
            "precision",
            "preact",
            "centred",
            "logit",
            "trusted",
            "average",
            "hold",
            "remedies",
            "averaged",
            "ant",
            "comparison",
            "table1",
        ],
        help=f"the stages to run (default: {' '.join(DEFAULT_STAGES)}) or, with --collect, to copy (default: "
        "all); weak (SAIL with weak teachers), precision (fp32 against bf16: it needs bf16 hardware), preact "
        "(SAIL with the actor's pre-tanh penalty), centred (SAIL with its reward centred at D = 1/2), logit "
        "(SAIL with D's logit), average (an averaged actor's tuning), hold (the teacher buffer held at its "
        "first refill), remedies (three remedies of the falls, tuned), averaged (the averaged actor's "
        "confirmation), ant (SAIL and DAC on Ant-v4), comparison "
        "(the paper's other rows) and table1 (SAIL at 1M) are never defaults",
    )
    parser.add_argument(
        "--envs",
        nargs="+",
        choices=list(TEACHER_FILES),
        metavar="ENV",
        help=f"only these envs' cells ({', '.join(TEACHER_FILES)})",
    )
    parser.add_argument("--seeds", nargs="+", type=int, metavar="SEED", help="only these seeds' cells")
    parser.add_argument(
        "--methods", nargs="+", choices=sorted(learners()), metavar="METHOD", help="only these methods' cells"
    )
    parser.add_argument(
        "--overrides",
        nargs="+",
        default=[],
        metavar="KEY=VALUE",
        help="Hydra overrides for every run, e.g. device=cuda optim.cudagraphs=true",
    )
    parser.add_argument("--jobs", type=runs_at_a_time, default=2, help="how many runs train at a time")
    parser.add_argument("--dry-run", action="store_true")
    parser.add_argument("--collect", type=Path, metavar="DEST", help="copy the finished runs' results, run nothing")
    parser.add_argument(
        "--status", action="store_true", help="how many runs are done or started under --out, run nothing"
    )
    args = parser.parse_args(argv)
    out = args.out.expanduser().resolve()
    if args.collect:
        for target in collect(out, args.collect, args.stages, args.envs, args.seeds, args.methods):
            print(target)
        return 0
    stages = args.stages or DEFAULT_STAGES
    cells = [
        c
        for c in plan()
        if c.stage in stages
        and (base_label(c) != "random" or args.random_teacher)
        and (args.envs is None or c.env in args.envs)
        and (args.seeds is None or c.seed in args.seeds)
        and (args.methods is None or c.method in args.methods)
    ]
    if not cells:
        parser.error(f"--stages {' '.join(stages)} has no cell with these --envs, --seeds and --methods")
    if args.status:
        print("\n".join(status(cells, out, args.jobs)))
        return 0
    if any(c.teacher.startswith("paper") for c in cells):  # --stages weak alone needs no paper teacher
        if args.teachers_dir is None:
            parser.error(f"--teachers-dir is required by --stages {' '.join(stages)}")
        needed = sorted({TEACHER_FILES[c.env] for c in cells if c.teacher.startswith("paper")})
        missing = [name for name in needed if not (args.teachers_dir / name).exists()]
        if missing:
            parser.error(f"--teachers-dir {args.teachers_dir} lacks {', '.join(missing)}")
    teachers_dir = None if args.teachers_dir is None else args.teachers_dir.resolve()
    weak_dir = args.weak_teachers_dir.resolve()
    weak = {base_label(c) for c in cells if c.stage in WEAK_STAGES} - {"paper", "random"}
    missing = sorted(label for label in weak if not (weak_dir / label).is_dir())
    if missing:
        parser.error(f"--weak-teachers-dir {weak_dir} lacks {', '.join(missing)} (see benchmarks/README.md)")
    device = device_of(args.overrides)
    if "precision" in stages and not args.dry_run and not native_bf16_matmul(device):
        parser.error(
            f"--stages precision runs optim.precision=bf16, which the {device} here emulates (a CPU without "
            "AVX-512 or AMX: many times slower, docs/performance.md): run it where bf16 is native, or on a GPU "
            "with --overrides device=cuda"
        )
    cells = started_first(cells, out)
    commands = [
        (
            cell,
            command(
                cell,
                out,
                teacher_path(cell, teachers_dir, args.random_teacher, weak_dir),
                extra=tuple(args.overrides),
            ),
        )
        for cell in cells
    ]
    if args.dry_run:
        for _, cmd in commands:
            print(shlex.join(cmd))
        return 0
    for cell in cells:  # aggregate.py labels runs from each stage folder's matrix.json
        # one label per teacher folder: "paper" is the authors' folder, a file per env
        teacher = (
            teachers_dir
            if cell.teacher.startswith("paper")
            else teacher_path(cell, teachers_dir, args.random_teacher, weak_dir)
        )
        record_matrix(out / cell.stage, [Teacher(cell.teacher, teacher)], [cell.method], [cell.env], [cell.seed])

    def launch(item) -> tuple[Cell, int]:
        cell, cmd = item
        run_dir = run_dir_of(cell, out)
        run_dir.mkdir(parents=True, exist_ok=True)
        start = time.time()
        with open(run_dir / "campaign.log", "a") as log:
            code = subprocess.run(
                cmd, cwd=REPO, stdout=log, stderr=subprocess.STDOUT, env={**os.environ, "WANDB_SILENT": "true"}
            ).returncode
        print(
            f"[campaign] {cell.stage} {cell.teacher} {cell.env} {cell.method} seed{cell.seed}: "
            f"exit {code} after {time.time() - start:.0f} s",
            flush=True,
        )
        return cell, code

    with ThreadPoolExecutor(args.jobs) as pool:
        failed = [cell for cell, code in pool.map(launch, commands) if code]
    for cell in failed:
        print(f"[campaign] failed: {cell}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
