"""What every training loop does besides building its pieces: seeds, cadences, evaluations, logs
and the run's summary (the run folder's life cycle itself is :mod:`torchrl_sail.harness`)."""

from __future__ import annotations

import contextlib
import math
import random
import time
import warnings
from pathlib import Path

import numpy as np
import torch
from config_schema import check_config, check_script
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf
from tensordict import TensorDict
from torchrl import timeit
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.record.loggers import get_logger

from torchrl_sail import TD3ExplorationPolicy
from torchrl_sail._compat import fast_tensor_outputs
from torchrl_sail.harness import (
    actor_summary,
    add_evaluation,
    checkpoint_dir,
    discriminator_summary,
    fall_share,
    last_checkpoint,
    new_run,
    plot_learning_curve,
    resume_mode,
    train_timing,
    wall_time,
    write_summary,
)

EXAMPLES_DIR = Path(__file__).resolve().parent


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def set_cpu_math(threads: int, flush_denormal: bool) -> None:
    """Whether denormal floats are flushed to zero, and torch's intra-op threads (0 keeps torch's default).

    Call it before any torch work: the flag is per thread, and torch's worker threads take it
    from the thread that creates them.
    """
    if not torch.set_flush_denormal(flush_denormal) and flush_denormal:
        warnings.warn(
            "flush_denormal=true: this CPU has no flush-to-zero mode (torch.set_flush_denormal returned False)",
            stacklevel=2,
        )
    if threads:
        torch.set_num_threads(threads)


def start_run(cfg: DictConfig, script: str) -> tuple[Path, bool | None]:
    """Check the config for ``script``, set threads, denormals and seeds, and say how the run folder starts.

    Also applies tensordict 0.15's shortcut for plain-tensor module outputs
    (:func:`torchrl_sail._compat.fast_tensor_outputs`): same results, less time per step.

    Returns the run folder (Hydra's output directory) and :func:`~torchrl_sail.harness.resume_mode`'s
    answer; ``None`` means a finished run under ``resume=auto``, which the caller skips.
    """
    check_script(cfg, script)
    check_config(cfg)
    set_cpu_math(cfg.threads, cfg.flush_denormal)
    fast_tensor_outputs()
    run_dir = Path(HydraConfig.get().runtime.output_dir)
    resuming = resume_mode(run_dir, cfg.resume, cfg.collector.total_frames, config=cfg)
    if resuming is None:  # resume=auto on a finished run (e.g. a rerun matrix)
        print(f"{run_dir} holds a finished run: skipped (resume=auto).")
    else:
        seed_everything(cfg.seed)
    return run_dir, resuming


def crossings(every: int, start: int, before: int, now: int) -> int:
    """How many multiples of ``every`` that are ``>= start`` lie in ``(before, now]`` (0 if ``every`` is 0).

    Every cadence of the loop (updates, evaluation, checkpoints) is derived from the frame count
    this way, so a resumed run needs no other counter.
    """
    if not every:
        return 0
    return max(0, now // every - (max(start, before + 1) - 1) // every)


def make_run(cfg: DictConfig) -> dict:
    """A fresh run state (``torchrl_sail.harness.new_run``) with this config's identity: env, algo, seed, teacher."""
    return new_run(env=cfg.env.name, algo=cfg.algo.name, seed=cfg.seed, teacher=cfg.teacher.path)


# ----------------------------------------------------------------------------- evaluation
def one_module_policy(actor):
    """A TD3 actor (``TensorDictSequential(TensorDictModule(MLP), TanhModule)``) as one module,
    :class:`~torchrl_sail.TD3ExplorationPolicy` without noise: the same action from the same
    modules (so a target actor's weights swapped into ``actor`` reach it) in one tensordict read and
    write per step (a rollout kept with it has no pre-tanh ``"param"`` key). Any other actor
    (SAC's, PPO's) is returned as it is."""
    return TD3ExplorationPolicy(actor) if TD3ExplorationPolicy.supports(actor) else actor


@torch.no_grad()
def evaluate_episodes(env, actor, episodes: int, max_steps: int, *, keep_rollouts: bool = False) -> list[dict]:
    """Deterministic episodes: the dense return, the delayed reward r_e and the length of each
    (and its ``"rollout"`` with ``keep_rollouts``).

    On one env (``batch_size=[]``), the episodes run one after the other. On a batched env
    (``make_sail_env(num_envs=episodes)``, :func:`utils.make_eval_env`) they run at once, one
    episode per env, until every one has ended or ``max_steps`` steps have run (an env that ends
    early is reset and its next episode ignored). Each env's episode starts where the episode of one
    env seeded like it would (the reset streams are put back after the ignored episodes, so every
    call uses one start state per env, whatever the episodes' lengths); the actor's batched forward
    pass rounds differently from one row at a time, so a long episode can drift from that one env's.
    """
    policy = one_module_policy(actor)
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        if env.batch_size:
            return episodes_at_once(env, policy, episodes, max_steps, keep_rollouts=keep_rollouts)
        results = []
        for _ in range(episodes):
            rollout = env.rollout(max_steps, policy, break_when_any_done=True)
            results.append(
                {
                    "dense_return": float(rollout["next", "episode_return"][-1]),
                    "delayed_reward": float(rollout["next", "reward"].sum()),
                    "length": rollout.numel(),
                    **({"rollout": rollout} if keep_rollouts else {}),
                }
            )
    return results


def episodes_at_once(env, policy, episodes: int, max_steps: int, *, keep_rollouts: bool = False) -> list[dict]:
    """:func:`evaluate_episodes` on a batched env of ``episodes`` envs, one episode each."""
    if tuple(env.batch_size) != (episodes,):
        raise ValueError(
            f"a batched env plays one episode per env: batch_size {tuple(env.batch_size)} for {episodes} episodes"
        )
    running = torch.ones(episodes, dtype=torch.bool)
    dense, delayed = torch.zeros(episodes), torch.zeros(episodes)
    length = torch.full((episodes,), max_steps)
    steps, td = [], env.reset()
    # the envs that end early are reset and play on: their reset streams are put back afterwards, so
    # that the next call's episodes start where they would have without those extra resets (TorchRL's
    # GymWrapper hands unknown attributes to the gymnasium vector env: ``envs`` is its list of envs)
    streams = [gymnasium_env.unwrapped.np_random.bit_generator for gymnasium_env in env.base_env.envs]
    kept = [stream.state for stream in streams]
    for step in range(max_steps):
        td, root = env.step_and_maybe_reset(policy(td))
        now = td["next"]
        delayed += torch.where(running, now["reward"].view(episodes), 0.0)
        # an episode's return is read where it ends; one cut by max_steps, after the last step
        ended = running & now["done"].view(episodes) if step < max_steps - 1 else running
        dense = torch.where(ended, now["episode_return"].view(episodes), dense)
        length = torch.where(ended, step + 1, length)
        running &= ~ended
        if keep_rollouts:
            steps.append(td)
        if not running.any():
            break
        td = root
    for stream, state in zip(streams, kept, strict=True):
        stream.state = state
    rollouts = torch.stack(steps, dim=1) if keep_rollouts else None
    return [
        {
            "dense_return": float(dense[i]),
            "delayed_reward": float(delayed[i]),
            "length": int(length[i]),
            **({"rollout": rollouts[i, : int(length[i])]} if keep_rollouts else {}),
        }
        for i in range(episodes)
    ]


def evaluate(env, actor, episodes: int, max_steps: int) -> float:
    """Mean dense return of deterministic episodes (reporting only; the learner never sees it)."""
    return sum(e["dense_return"] for e in evaluate_episodes(env, actor, episodes, max_steps)) / episodes


# the file keys of each actor's weights in best_policy.pt and best_evaluated_policy.pt (and KeptPolicy's state)
ACTOR_KEYS = {"online": "actor", "target": "target_actor", "average": "average_actor"}


def actor_names(cfg: DictConfig) -> list[str]:
    """The actors a run of ``cfg`` has, by the name ``eval.actor`` gives them: ``online``; ``target``
    for a TD3 learner; ``average`` with ``eval.average_frames`` (:class:`ActorAverage`)."""
    return [
        "online",
        *(["target"] if cfg.algo.learner == "td3" else []),
        *(["average"] if cfg.eval.average_frames else []),
    ]


def learning_start(cfg: DictConfig) -> int:
    """The frame learning starts: ``optim.start_frames``, else the end of the random warm-up."""
    return cfg.optim.start_frames if cfg.optim.start_frames is not None else cfg.collector.init_random_frames


def make_actor_average(cfg: DictConfig, loss) -> ActorAverage | None:
    """``eval.average_frames``' :class:`ActorAverage` of ``loss``'s actor, from the frame learning
    starts (``optim.start_frames``, else the end of the random warm-up); ``None`` when it is 0."""
    if not cfg.eval.average_frames:
        return None
    return ActorAverage(loss.actor_network_params, memory_frames=cfg.eval.average_frames, start=learning_start(cfg))


def actor_weights(loss, average: ActorAverage | None = None) -> dict:
    """The weights of every actor a run has, by the name ``eval.actor`` gives it: ``"online"`` (the
    actor the loss trains), ``"target"`` (a TD3 loss's target actor) and ``"average"`` (``average``'s,
    :class:`ActorAverage`). Live tensors: they change as the run trains."""
    weights = {"online": loss.actor_network_params}
    if getattr(loss, "delay_actor", False):  # TD3's; SACLoss answers target_actor_network_params too
        weights["target"] = loss.target_actor_network_params
    if average is not None:
        weights["average"] = average.weights
    return weights


def actor_returns(env, actor, weights, episodes: int, max_steps: int) -> list[float]:
    """Dense returns of deterministic episodes of ``actor``, run with ``weights`` in place of its own
    (one entry of :func:`actor_weights`; ``None``: its own). Its own come back after the episodes."""
    with weights_in(actor, weights):
        return [e["dense_return"] for e in evaluate_episodes(env, actor, episodes, max_steps)]


def weights_in(actor, weights):
    """A context in which ``actor`` runs with ``weights`` (``None``: its own), its own back after it."""
    if weights is None:
        return contextlib.nullcontext()
    # preserve_module_state=False: the swapped-in tensors stay the ones the run saves and updates
    return weights.to_module(actor, preserve_module_state=False)


def evaluation_metrics(returns: list[float], teacher_return: float, suffix: str = "") -> dict:
    """An evaluation's logged figures from its episodes' returns: ``eval/return`` (their mean),
    ``eval/min_return`` (the lowest episode's return) and ``eval/below_teacher``, the share of its
    episodes below the teacher's return (one fallen episode in 10 reads 0.1, a collapse 1.0); each
    tag with ``suffix`` (``"_online"``, ``"_target"``, ``"_average"``: another actor's).

    Examples:
        >>> evaluation_metrics([300.0, 100.0, 350.0, 250.0], teacher_return=200.0)
        {'eval/return': 250.0, 'eval/min_return': 100.0, 'eval/below_teacher': 0.25}
    """
    return {
        f"eval/return{suffix}": sum(returns) / len(returns),
        f"eval/min_return{suffix}": min(returns),
        f"eval/below_teacher{suffix}": sum(value < teacher_return for value in returns) / len(returns),
    }


def record_evaluation(eval_env, actor, actors, cfg: DictConfig, run: dict, frames: int, teacher_return: float) -> dict:
    """The loops' evaluation at ``frames`` of the actor ``eval.actor`` names (its weights in
    ``actors``, :func:`actor_weights`; ``None``: ``actor`` alone): its :func:`evaluation_metrics`, the
    mean return kept in ``run["evals"]`` with the first frame it beat the teacher
    (``run["passed_teacher_at"]``)."""
    weights = None if actors is None or cfg.eval.actor == "online" else actors[str(cfg.eval.actor)]
    returns = actor_returns(eval_env, actor, weights, cfg.eval.episodes, cfg.env.max_episode_steps)
    metrics = evaluation_metrics(returns, teacher_return)
    add_evaluation(run, frames, metrics["eval/return"], teacher_return)
    return metrics


class ActorAverage:
    """An exponential moving average of the actor's weights over frames: an actor to evaluate, keep
    and ship (``eval.actor=average``) whose memory is set in frames, where TD3's target actor
    remembers about ``policy_delay / tau`` gradient steps.

    After each collector batch, :meth:`update` moves the average toward the actor's weights by
    ``1 - exp(-n / memory_frames)`` for the batch's ``n`` frames, so the actor's weights of ``k``
    frames ago weigh in proportion to ``exp(-k / memory_frames)``. The batch that reaches ``start``
    (the frame learning starts; its own learning block runs in that batch) sets the average to the
    actor's weights; while fewer than about ``memory_frames`` frames have passed since, the step is
    ``n / (frames - start)`` instead, the uniform average of the weights since ``start``: the
    initial weights do not linger. A checkpoint component (``state_dict``).

    Args:
        weights: the actor's live weights (``loss.actor_network_params``).
        memory_frames (int): the average's memory, in frames (``eval.average_frames``).
        start (int): the frame learning starts.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> live = TensorDict({"w": torch.tensor([0.0])})
        >>> average = ActorAverage(live, memory_frames=1000, start=0)
        >>> live["w"] += 4.0
        >>> average.update(before=0, frames=100)  # the uniform average of one: the actor's weights
        >>> live["w"] += 4.0
        >>> average.update(before=100, frames=200)  # the uniform average of (4, 8), as 1/2 > 1 - exp(-0.1)
        >>> average.weights["w"].tolist()
        [6.0]
    """

    def __init__(self, weights, *, memory_frames: int, start: int) -> None:
        self.live = weights
        self.weights = weights.data.clone()
        self.memory_frames, self.start = memory_frames, start

    def update(self, *, before: int, frames: int) -> None:
        """Moves the average toward the actor's weights for the frames in ``(before, frames]``."""
        if frames < self.start:
            return
        if before < self.start:  # the batch that reaches start: the average begins at the actor
            self.weights.update_(self.live.data)
            return
        n = frames - before
        step = max(-math.expm1(-n / self.memory_frames), n / (frames - self.start))
        self.weights.lerp_(self.live.data, step)

    def state_dict(self) -> dict:
        return {"weights": self.weights.flatten_keys(".").to_dict()}

    def load_state_dict(self, state: dict) -> None:
        self.weights.update_(TensorDict(state["weights"]).unflatten_keys("."))


class KeptPolicy:
    """Copies of the weights of every actor a run has (the actor's, a TD3 loss's target actor's, an
    averaged actor's), taken whenever a score of the run reaches a strictly higher value: what
    :class:`BestPolicy` and :class:`BestEvaluatedPolicy` keep. The copy lives in memory and is written
    to its file by :meth:`write`, at the run's checkpoints, so the file always matches the checkpoint
    a resume continues from. A checkpoint component (``state_dict``).

    Args:
        actors: the live weights of each actor by name (:func:`actor_weights`).
    """

    score_name = "score"  # the score's name in record(): what the rule compares

    def __init__(self, actors: dict) -> None:
        self.live = {ACTOR_KEYS[name]: weights for name, weights in actors.items()}
        self.kept = {name: params.data.clone() for name, params in self.live.items()}
        self.score: float | None = None  # the best score so far
        self.frames: int | None = None  # the frame it was reached at

    def keep(self, score: float, frames: int) -> bool:
        """Keeps the actors' weights of now if ``score`` is a new high. Returns whether it did."""
        if self.score is not None and score <= self.score:
            return False
        self.score, self.frames = score, frames
        for name, params in self.live.items():
            self.kept[name].update_(params.data)
        return True

    def params(self, which: str):
        """The kept weights of the actor ``which`` names (``"online"``, ``"target"``, ``"average"``),
        keyed as the loss keeps them: ``with kept.params(which).to_module(actor): ...`` runs the kept policy."""
        return self.kept[ACTOR_KEYS[str(which)]]

    def record(self) -> dict:
        return {"frames": self.frames, self.score_name: self.score}

    def write(self, path: Path) -> None:
        """The kept weights (each as ``{name: tensor}``) and :meth:`record`, written atomically to
        ``path``; nothing while no policy is kept."""
        if self.frames is None:
            return
        state = {**self.record(), **{name: kept.flatten_keys(".").to_dict() for name, kept in self.kept.items()}}
        tmp = path.with_name(f".{path.name}.tmp")
        torch.save(state, tmp)
        tmp.replace(path)

    def state_dict(self) -> dict:
        return {
            "score": self.score,
            "frames": self.frames,
            **{name: kept.flatten_keys(".").to_dict() for name, kept in self.kept.items()},
        }

    def load_state_dict(self, state: dict) -> None:
        # a BestPolicy checkpointed before KeptPolicy held its score as "mean"
        self.score, self.frames = state["score"] if "score" in state else state["mean"], state["frames"]
        for name, kept in self.kept.items():
            kept.update_(TensorDict(state[name]).unflatten_keys("."))


class BestPolicy(KeptPolicy):
    """The policy a run keeps as its best, chosen only from its own training returns: the SAIL
    authors' rule (their ``train_sail.py`` callback saves ``best_model.pkl``), ``best_policy.pt``.

    Every ``every_frames`` frames, the mean return of the last ``window`` finished training
    episodes is compared with the best so far; a strictly higher mean keeps a copy of the weights
    of every actor the run has (:class:`KeptPolicy`).

    Args:
        actors: the live weights of each actor by name (:func:`actor_weights`).
        every_frames (int): how often the window's mean is compared (the authors': 500).
        window (int): how many of the latest training episodes are averaged (the authors': 100).

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> actor = TensorDict({"w": torch.zeros(2)})  # stands in for loss.actor_network_params
        >>> best = BestPolicy({"online": actor}, every_frames=500, window=2)
        >>> best.observe(torch.tensor([10.0, 20.0]), before=0, frames=500)  # mean 15: kept
        True
        >>> actor["w"] += 1.0
        >>> best.observe(torch.tensor([5.0]), before=500, frames=1000)  # mean of (20, 5) 12.5: not kept
        False
        >>> best.record(), best.kept["actor"]["w"].tolist()
        ({'frames': 500, 'train_return_mean': 15.0, 'window': 2}, [0.0, 0.0])
    """

    score_name = "train_return_mean"

    def __init__(self, actors: dict, *, every_frames: int, window: int) -> None:
        super().__init__(actors)
        self.every_frames, self.window = every_frames, window
        self.returns: list[float] = []

    def observe(self, returns: torch.Tensor, *, before: int, frames: int) -> bool:
        """Adds the training episodes that ended in ``(before, frames]``; at a multiple of
        ``every_frames`` in there, keeps the policy if the window's mean is a new high. Returns
        whether it did."""
        self.returns = (self.returns + returns.tolist())[-self.window :]
        if not self.returns or not crossings(self.every_frames, 0, before, frames):
            return False
        return self.keep(sum(self.returns) / len(self.returns), frames)

    def record(self) -> dict:
        return {**super().record(), "window": self.window}

    def state_dict(self) -> dict:
        return {**super().state_dict(), "returns": list(self.returns)}

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.returns = list(state["returns"])


class BestEvaluatedPolicy(KeptPolicy):
    """The policy at a run's best periodic evaluation: the weights of every actor at the highest
    ``eval/return`` of the actor ``eval.actor`` names (Stable-Baselines3's ``EvalCallback`` keeps
    its ``best_model`` so), ``best_evaluated_policy.pt``. The evaluations' episodes choose it; the
    figure reported for it comes from other episodes (:func:`evaluate_kept_policy`), as a choice's
    own episodes overstate it.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> actor = TensorDict({"w": torch.zeros(2)})
        >>> best = BestEvaluatedPolicy({"online": actor})
        >>> best.keep(250.0, frames=10_000), best.keep(240.0, frames=20_000)
        (True, False)
        >>> best.record()
        {'frames': 10000, 'periodic_eval_return': 250.0}
    """

    score_name = "periodic_eval_return"


def evaluate_kept_policy(cfg: DictConfig, kept: KeptPolicy, actor, make_eval_env) -> dict:
    """``kept``'s record and, once a policy is kept, its ``eval.best_policy.episodes`` deterministic
    episodes (the actor ``eval.actor`` names) on ``make_eval_env(cfg, seed + 20000, episodes)``
    (:func:`utils.make_eval_env`: the stream ``examples/evaluate.py`` uses by default, which no
    evaluation during training ran): the summary's ``best_policy`` and ``best_evaluated_policy``."""
    record, episodes = kept.record(), cfg.eval.best_policy.episodes
    if record["frames"] is None or not episodes:
        return record
    with kept.params(cfg.eval.actor).to_module(actor, preserve_module_state=False):
        env = make_eval_env(cfg, cfg.seed + 20_000, episodes)
        record["eval_return"] = evaluate(env, actor, episodes, cfg.env.max_episode_steps)
    return {**record, "actor": str(cfg.eval.actor), "episodes": episodes, "seed": cfg.seed + 20_000}


def load_kept_policy(path: Path, loss, which: str) -> dict:
    """Puts the weights of a kept policy's file (``best_policy.pt``, ``best_evaluated_policy.pt``:
    :class:`KeptPolicy`) for the actor ``which`` names into ``loss``'s actor, and returns the file's
    record (the frame it was kept at and the score that kept it)."""
    if not Path(path).exists():
        raise FileNotFoundError(
            f"{path}: no such kept policy (a run writes it at its checkpoints once it keeps one; "
            f"runs of torchrl_sail versions before it have none)"
        )
    state = torch.load(path, weights_only=True)
    name = ACTOR_KEYS[str(which)]
    if name not in state:
        raise ValueError(f"{path}: holds no {which} actor (only {sorted(k for k in state if 'actor' in k)})")
    loss.actor_network_params.data.update_(TensorDict(state[name]).unflatten_keys("."))
    return {key: value for key, value in state.items() if key not in ACTOR_KEYS.values()}


# ----------------------------------------------------------------------------- logs and summary
def make_loggers(cfg: DictConfig, run_dir: Path, states: dict) -> dict:
    """TorchRL loggers by backend name; ``states`` (saved ``logger.state_dict()``) resumes them."""
    loggers = {}
    for backend in dict.fromkeys(["csv", *cfg.logger.backends]):  # csv always, once
        kwargs = {}
        if backend == "wandb":
            # get_logger forwards only `wandb_kwargs`; offline mode needs no account.
            kwargs = {
                "wandb_kwargs": {
                    "offline": cfg.logger.wandb_mode == "offline",
                    "project": cfg.logger.project,
                    "config": OmegaConf.to_container(cfg, resolve=True, enum_to_str=True),
                }
            }
        if backend in states:
            kwargs["state_dict"] = states[backend]  # e.g. wandb: log to the same run id
        loggers[backend] = get_logger(backend, logger_name=str(run_dir), experiment_name="logs", **kwargs)
    return loggers


def logger_states(loggers: dict) -> dict:
    # The CSV logger's state is its history, already on disk: resume truncates the files instead.
    return {name: logger.state_dict() for name, logger in loggers.items() if name != "csv"}


def log_metrics(loggers, metrics: dict, step: int) -> None:
    values = {k: float(v.detach()) if torch.is_tensor(v) else float(v) for k, v in metrics.items() if v is not None}
    # Learned quantities reach here finite (DivergenceCheck runs first); what is dropped is
    # bookkeeping, e.g. the promotion threshold, -inf until the window W_k holds a trajectory.
    metrics = {k: v for k, v in values.items() if math.isfinite(v)}
    for logger in loggers.values():
        logger.log_metrics(metrics, step)


class RunClock:
    """The run's time: this start's wall clock and frame rate, the run's wall time over all its
    starts (``run["wall_seconds"]`` of the earlier ones), and the timed part after warm-up
    (TorchRL's ``timeit`` sections restart there)."""

    def __init__(self, run: dict, frames: int, *, warmup: int = 0) -> None:
        self.start, self.start_frames, self.wall_before = time.time(), frames, run["wall_seconds"]
        self.warmup, self.train_clock, self.end = warmup, None, None

    def batches(self, collector, frames: int):
        """The collector's batches, each timed (``collect``); the timed part starts at the first
        batch collected after warm-up. No batch for a run with no frames left."""
        iterator = iter(collector if collector.total_frames else ())
        while True:
            if self.train_clock is None and frames >= self.warmup:
                timeit.erase()
                self.train_clock = (time.time(), frames)
            with timeit("collect"):
                data = next(iterator, None)
            if data is None:
                return
            frames += data.numel()
            yield data

    def fps(self, frames: int) -> float:
        return (frames - self.start_frames) / max((self.end or time.time()) - self.start, 1e-9)

    def wall_seconds(self) -> float | None:
        return wall_time(self.wall_before, self.start, time.time())

    def stop(self) -> None:
        self.end = time.time()

    def summary(self, frames: int) -> dict:
        """The summary's speed entries: this start's frames per second and the timed part's."""
        return {"frames_per_second": self.fps(frames), **train_timing(self.train_clock, end=self.end, frames=frames)}


class RunCheckpoint:
    """Saves the run where it stands: the divergence check first (NaN/inf stops the run before anything
    is written), then the run's counters, logger states and wall time, the checkpoint, and the files
    that must match it (``after_save``, e.g. ``BestPolicy``'s ``best_policy.pt``).

    ``check(metrics, frames)`` runs the divergence check alone (at the logging cadence).
    """

    def __init__(
        self, checkpoint, run_dir: Path, run: dict, *, loggers: dict, divergence, clock: RunClock, after_save=()
    ):
        self.checkpoint, self.run_dir, self.run, self.loggers = checkpoint, run_dir, run, loggers
        self.divergence, self.clock, self.after_save = divergence, clock, list(after_save)

    def check(self, metrics: dict, frames: int) -> None:
        self.divergence(metrics, frame=frames, checkpoint=last_checkpoint(self.run_dir, self.run))

    def __call__(self, metrics: dict, *, frames: int, **counters) -> None:
        self.check(metrics, frames)
        self.run.update(
            frames=frames, **counters, loggers=logger_states(self.loggers), wall_seconds=self.clock.wall_seconds()
        )
        self.checkpoint.save(checkpoint_dir(self.run_dir))
        for write in self.after_save:
            write()


def write_run_summary(
    run_dir: Path,
    cfg: DictConfig,
    run: dict,
    *,
    teacher_return: float,
    teacher_source: str,
    clock: RunClock | None = None,
    alpha_switch_frame: int | None = None,
    **results,
) -> None:
    """The finished run's ``learning_curve.png`` and ``summary.json`` (``torchrl_sail.harness``), for every
    training script: the run's env, algo, seed, teacher and budget; from ``run``, its counters, its
    evaluations (last, best, the first to pass the teacher, the fall share) and its starts; from
    ``clock``, this start's speeds; then ``results`` (what only this script has), memory and provenance."""
    plot_learning_curve(
        run_dir,
        teacher_return=teacher_return,
        alpha_switch_frame=alpha_switch_frame,
        title=f"{cfg.algo.name} on {cfg.env.name}, seed {cfg.seed}",
    )
    evals = [value for _, value in run["evals"]]
    write_summary(
        run_dir,
        {
            "env": cfg.env.name,
            "algo": cfg.algo.name,
            "seed": cfg.seed,
            "teacher_return": teacher_return,
            "teacher_source": teacher_source,
            "total_frames": 0 if results.get("offline") else cfg.collector.total_frames,
            "alpha_switched_at_frame": alpha_switch_frame,
            "frames": run["frames"],
            "gradient_steps": run["gradient_steps"],
            "final_eval_return": evals[-1] if evals else None,
            "best_eval_return": max(evals) if evals else None,
            "passed_teacher_at_frame": run["passed_teacher_at"],
            "fall_share": fall_share(run["evals"], teacher_return),
            "resumes": run["resumes"],
            "starts": run["starts"],
            "wall_seconds": run["wall_seconds"],
            **(clock.summary(run["frames"]) if clock is not None else {}),
            **results,
            # D's saturation, skipped steps and last statistics, from the logs (absent without a D)
            **({"discriminator": d} if (d := discriminator_summary(run_dir)) is not None else {}),
            # the TD3 actor's tanh saturation, from the logs (absent for SAC, PPO and BC)
            **({"actor": a} if (a := actor_summary(run_dir)) is not None else {}),
        },
        code_dir=EXAMPLES_DIR,
    )
