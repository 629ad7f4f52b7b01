"""The steps of the off-policy training loop (``sail_td3.py``), one object per step of Algorithm 1.

Each step is built from the config once (``make_*``) and called once per collected batch with the
frame window ``(before, frames]`` that batch covers: it acts on the cadences that fall in the window
and returns the metrics to log (``{}`` when nothing was due). A method's extra behaviour is a part
of the step it belongs to, chosen by the config when the step is built: DDPGfD's n-step views and
DAC's absorbing states are how :class:`TransitionStore` stores rows, SAIL-OnPolicy's recent window
is one more buffer it fills; the learning blocks (:func:`make_learning_blocks`) run on the SAIL
authors' frame cadence or after each episode (:class:`FrameCadence`, :class:`EpisodeCadence`), in
either order; an actor learning-rate decay (:class:`ActorLRDecay`) runs inside :class:`TD3Block`;
RND's predictor (:class:`PredictorUpdate`) learns inside :class:`DiscriminatorBlock`, which a
method without a D does not have; the other actors' evaluations and videos are part of
:class:`Evaluations`.
"""

from __future__ import annotations

import contextlib

import torch
from omegaconf import DictConfig
from run_utils import (
    actor_names,
    actor_returns,
    crossings,
    evaluation_metrics,
    learning_start,
    record_evaluation,
    weights_in,
)
from tensordict.nn import TensorDictModuleBase
from torchrl import timeit
from utils import (
    ActorDrift,
    actor_lr,
    actor_saturation,
    discriminator_block,
    make_absorbing,
    make_nstep,
    make_replay,
    stored_keys,
)
from video import log_video, make_render_env

from torchrl_sail import TRANSITION_KEYS, MixedReplayBuffer, PrioritizedMixedReplayBuffer

# ----------------------------------------------------------------------------- store and promote


class TransitionStore:
    """Algorithm 1's "store the transitions": a collected batch's rows into the agent's buffers.

    Args:
        buffers: every buffer a stored row goes to (the replay buffer; SAIL-OnPolicy's recent window too).
        nstep: DDPGfD's :class:`~torchrl_sail.NStepTransform` (``None``: one-step rows). It works per
            env stream across batches, so a step is stored once the ``n`` steps after it are collected.
        absorbing: DAC's :class:`~torchrl_sail.AbsorbingStateTransform` (``None``: no absorbing states).
    """

    def __init__(self, buffers, *, nstep=None, absorbing=None) -> None:
        self.buffers, self.nstep, self.absorbing = list(buffers), nstep, absorbing

    def __call__(self, data) -> None:
        if self.nstep is None:
            stored = data.reshape(-1).select(*TRANSITION_KEYS)
        else:  # time last per env stream; flatten, not reshape(-1): TensorDict sizes an empty batch as 1 row
            stored = self.nstep.inv(data.select(*TRANSITION_KEYS)).flatten(0, -1)
        if self.absorbing is not None:
            stored = self.absorbing.add_absorbing_transitions(stored)
        if stored.shape[0]:  # the first batches of an n-step run can all be waiting
            for buffer in self.buffers:
                buffer.extend(stored)


def make_recent(cfg: DictConfig, replay):
    """The transitions D learns the agent's side from: SAIL-OnPolicy's window of the most recent
    ``algo.recent_window`` rows (``algo.discriminator_agent_data=recent``), else the replay buffer itself."""
    if cfg.algo.discriminator_agent_data == "recent":
        return make_replay(cfg.algo.recent_window, cfg.device)
    return replay


def make_transition_store(cfg: DictConfig, replay, recent, action_spec) -> TransitionStore:
    """The store of ``cfg``'s method; the agent's absorbing rows store ``algo.absorbing_action``."""
    buffers = [replay] if recent is replay else [replay, recent]
    return TransitionStore(buffers, nstep=make_nstep(cfg), absorbing=make_absorbing(cfg, action_spec))


class TeacherUpdate:
    """Algorithm 1's teacher update: every finished trajectory with ``r_e > C`` joins the teacher
    buffer (``adaptive``; the no-adaptation ablation keeps its demonstrations) until ``max_promoted``
    trajectories were promoted (``None``: no limit; a batch may promote several), then alpha follows
    the promotions (``alpha_scheduler.step``).

    Called with a batch and the frame count after it; returns alpha for the batch's TD3 block and
    ``{"alpha_switch_frame": frames}`` at the batch where alpha changed (else ``{}``).
    """

    def __init__(self, teacher, alpha_scheduler, *, adaptive: bool, max_promoted: int | None = None) -> None:
        self.teacher, self.alpha_scheduler, self.adaptive = teacher, alpha_scheduler, adaptive
        self.max_promoted = max_promoted

    def __call__(self, data, frames: int) -> tuple[float, dict]:
        if self.adaptive and (self.max_promoted is None or self.teacher.writer.num_promoted < self.max_promoted):
            self.teacher.extend(data)
        before = self.alpha_scheduler.alpha
        alpha = self.alpha_scheduler.step(frames=frames, num_promoted=self.teacher.writer.num_promoted)
        return alpha, ({"alpha_switch_frame": frames} if alpha != before else {})


def finished_episodes(data, best_policy, *, before: int, frames: int) -> dict:
    """The training episodes that ended in the batch: their returns go to the best-policy rule
    (:class:`~run_utils.BestPolicy`), their means to the logs (``train/*``; RND's bonus too)."""
    flat = data.reshape(-1)
    done = flat["next", "done"].squeeze(-1)
    best_policy.observe(flat["next", "episode_return"][done].reshape(-1), before=before, frames=frames)
    metrics = {}
    if done.any():
        metrics["train/dense_return"] = flat["next", "episode_return"][done].mean()
        metrics["train/delayed_reward"] = flat["next", "reward"][done].mean()
        metrics["train/episode_length"] = flat["step_count"][done].float().mean() + 1
    bonus = flat.get(("next", "intrinsic_reward"), None)  # SAIL-RND's
    if bonus is not None:
        metrics["train/intrinsic_reward"] = bonus.mean()
    return metrics


# ----------------------------------------------------------------------------- the two learning blocks


class FrameCadence:
    """``steps`` every ``every_frames`` frames from frame ``start`` on (the SAIL authors' cadence): a
    batch that crosses ``k`` such multiples gets ``k * steps``."""

    def __init__(self, *, every_frames: int, steps: int, start: int) -> None:
        self.every_frames, self.steps, self.start = every_frames, steps, start

    def __call__(self, before: int, frames: int, data) -> int:
        return crossings(self.every_frames, self.start, before, frames) * self.steps

    def began_at(self, before: int, data) -> int:
        """The frame count a block's schedules read: the frames before the collector batch."""
        return before


class EpisodeCadence:
    """After each finished episode, ``steps_per_frame`` steps per frame of that episode, for the
    episodes that end at frame ``start`` or later (Kostrikov et al.'s DAC: training after every
    episode once the buffer holds ``start`` samples). ``data`` is one env's ``[T]`` batch (time last);
    an episode's length is its last ``step_count + 1``."""

    def __init__(self, *, steps_per_frame: float, start: int) -> None:
        self.steps_per_frame, self.start = steps_per_frame, start

    def __call__(self, before: int, frames: int, data) -> int:
        _, lengths = self._counted(before, data)
        return round(self.steps_per_frame * int(lengths.sum()))

    def began_at(self, before: int, data) -> int:
        """The frame count a block's schedules read: the frames before the first counted episode
        began (the release sets the actor's learning rate before each episode's rollout)."""
        ended_at, lengths = self._counted(before, data)
        return int((ended_at - lengths).min()) if len(ended_at) else before

    def _counted(self, before: int, data) -> tuple[torch.Tensor, torch.Tensor]:
        """The frame count at the last step, and the length, of each episode that ended in ``data``
        from ``start`` on."""
        flat = data.reshape(-1)
        done = flat["next", "done"].reshape(-1)
        ended_at = before + 1 + done.nonzero().reshape(-1)
        lengths = flat["step_count"].reshape(-1)[done] + 1
        counted = ended_at >= self.start
        return ended_at[counted], lengths[counted]


def make_cadence(cfg: DictConfig, *, every_frames: int, steps: int):
    """``optim.cadence``: ``frames`` (every ``every_frames`` frames, ``steps`` steps) or ``episodes``
    (after each episode, the same steps per frame); learning starts at ``optim.start_frames``
    (``None``: when the random warm-up ends)."""
    start = learning_start(cfg)
    if cfg.optim.cadence == "episodes":
        return EpisodeCadence(steps_per_frame=steps / every_frames, start=start)
    return FrameCadence(every_frames=every_frames, steps=steps, start=start)


class ActorLRDecay:
    """A stepwise decay of the actor's learning rate, a function of frames (a resume continues it):
    ``lr * rate ** (frames // every_frames)`` (``optim.actor_lr_decay``; Kostrikov et al.'s DAC)."""

    def __init__(self, optimizer, lr: float, *, rate: float, every_frames: int) -> None:
        self.optimizer, self.lr, self.rate, self.every_frames = optimizer, lr, rate, every_frames

    def __call__(self, frames: int) -> dict:
        lr = self.lr * self.rate ** (frames // self.every_frames)
        for group in self.optimizer.param_groups:
            group["lr"] = lr
        return {"sail/actor_lr": lr}


def make_td3_batches(cfg: DictConfig, teacher, replay, reward):
    """The TD3 batches: ``round(alpha * B)`` teacher rows each (``MixedReplayBuffer``), or DDPGfD's
    prioritized replay over the demonstrations and the replay together (``algo.per``)."""
    keys, per = stored_keys(cfg), cfg.algo.per
    if per is None:
        return MixedReplayBuffer(teacher, replay, transform=reward, row_id_key="row_id", keys=keys)
    return PrioritizedMixedReplayBuffer(
        teacher,
        replay,
        alpha=per.alpha,
        beta=per.beta,
        eps=per.eps,
        teacher_eps=per.teacher_eps,
        transform=reward,
        row_id_key="row_id",
        keys=keys,
    )


class PrioritizedUpdate:
    """DDPGfD's step on a prioritized batch: the TD3 step, then its rows' new priorities,
    ``delta^2 + lambda_3 |grad_a Q_1(s, a)|^2`` (the buffer adds ``eps``, and ``eps_D`` on
    demonstration rows).

    ``delta^2`` is the step's own squared 1-step TD error, the max over the twin critics
    (``TD3Update(td_error=True)``, TorchRL's TD3 priority); the action gradient is the first
    critic's (the one the actor climbs) at the batch's actions, taken before the step as the TD
    error is.
    """

    def __init__(self, update, buffer: PrioritizedMixedReplayBuffer, loss, *, action_grad_coef: float) -> None:
        self.update, self.buffer, self.loss, self.action_grad_coef = update, buffer, loss, action_grad_coef

    def __call__(self, batch, update_actor: bool) -> dict:
        grad_term = self.action_grad_coef * self.action_gradient(batch) if self.action_grad_coef else 0.0
        metrics = self.update(batch, update_actor=update_actor)
        with timeit("priority"):
            self.buffer.update_priority(batch[self.buffer.index_key], batch[self.loss.tensor_keys.priority] + grad_term)
        return metrics

    def action_gradient(self, batch) -> torch.Tensor:
        """``|grad_a Q_1(s, a)|^2`` per row."""
        loss = self.loss
        critic, action_key = loss.qvalue_network, loss.tensor_keys.action
        action = batch[action_key].detach().requires_grad_(True)
        inputs = batch.select(*critic.in_keys).set(action_key, action)  # a new tensordict: batch keeps its action
        with torch.enable_grad(), loss.qvalue_network_params[0].to_module(critic):
            q = critic(inputs)[loss.tensor_keys.state_action_value]
            (grad,) = torch.autograd.grad(q.sum(), action)
        return grad.pow(2).sum(-1)


def make_prioritized_update(cfg: DictConfig, update, batches, loss):
    """``update``, setting DDPGfD's priorities after each step with ``algo.per`` (unchanged without)."""
    per = cfg.algo.per
    return update if per is None else PrioritizedUpdate(update, batches, loss, action_grad_coef=per.action_grad_coef)


class RandomEpisodesUntil(TensorDictModuleBase):
    """Kostrikov et al.'s release: uniform random actions, whole episodes at a time, until the first
    episode that starts once ``started()`` holds (their actor's first update); ``policy`` from then on.

    An episode starts where the env's ``init_key`` is set (TorchRL's ``InitTracker``). A resumed run
    starts on a fresh episode, so it acts with ``policy`` from its first step if ``started()`` holds.

    Args:
        policy: the exploration policy (a TensorDict module writing ``action_key``).
        action_spec: the env's action spec; its ``rand`` draws the random actions.
        started: ``started() -> bool``, e.g. :attr:`TD3Block.actor_started`.
        action_key, init_key: the action and the episode-start flag.
    """

    def __init__(self, policy, action_spec, started, *, action_key="action", init_key="is_init") -> None:
        super().__init__()
        self.policy, self.action_spec, self.started = policy, action_spec, started
        self.action_key, self.init_key = action_key, init_key
        self.in_keys = [*policy.in_keys, init_key]
        self.out_keys = list(policy.out_keys)
        self.random = True

    def forward(self, tensordict):
        if self.random and self.started() and bool(tensordict[self.init_key].all()):
            self.random = False
        if self.random:
            return tensordict.set(self.action_key, self.action_spec.rand(tensordict.batch_size))
        return self.policy(tensordict)


class TD3Block:
    """Algorithm 1's policy update: as many gradient steps as ``cadence`` gives the batch, on batches
    of ``batch_size`` rows, ``round(alpha * batch_size)`` of them the teacher's (alpha as
    ``alpha_scheduler`` holds it).

    Neither the buffers nor D change inside a block, so its batches are drawn, and rewarded by
    the current D, in one call (``batches.sample``, under ``precision``). From a
    :class:`~torchrl_sail.PrioritizedMixedReplayBuffer` (DDPGfD), each step draws its own batch,
    since the step before changed the priorities (``update`` sets them: :class:`PrioritizedUpdate`).

    Args:
        batches: a :class:`~torchrl_sail.MixedReplayBuffer` of the teacher and replay buffers whose
            transform writes the reward, or a :class:`~torchrl_sail.PrioritizedMixedReplayBuffer`.
        update: ``update(batch, update_actor) -> metrics``, one gradient step (``utils.make_update``).
        cadence: ``cadence(before, frames, data) -> steps`` (:class:`FrameCadence`, :class:`EpisodeCadence`).
        alpha_scheduler: holds the teacher share, ``.alpha``.
        policy_delay, actor_updates_after: the actor steps at every ``policy_delay``-th gradient step
            from step ``actor_updates_after`` on.
        update_targets: the target networks' Polyak step alone, run at every ``policy_delay``-th
            gradient step before the actor starts (Kostrikov et al.'s release moves the critic's
            target from the first step on; the actor's, its actor unchanged, stays where it is).
        reward_tag: the metric that logs the block's mean reward.
        lr_decay: an :class:`ActorLRDecay`, run before each block at the cadence's ``began_at``
            frame count (``None``: a constant rate).
        drift: an :class:`~utils.ActorDrift` measured over each block (``None`` for SAC).
        saturation: ``saturation(batch) -> metrics`` on the block's last batch while it holds agent rows.
        gradient_steps: the steps done before (a resumed run's).
    """

    def __init__(
        self,
        batches,
        update,
        *,
        cadence,
        alpha_scheduler,
        batch_size: int,
        policy_delay: int,
        actor_updates_after: int,
        reward_tag: str,
        precision=None,
        lr_decay: ActorLRDecay | None = None,
        drift: ActorDrift | None = None,
        saturation=None,
        update_targets,
        gradient_steps: int = 0,
    ) -> None:
        self.batches, self.update, self.cadence, self.alpha_scheduler = batches, update, cadence, alpha_scheduler
        self.batch_size, self.policy_delay, self.actor_updates_after = batch_size, policy_delay, actor_updates_after
        self.reward_tag = reward_tag
        self.precision = precision if precision is not None else contextlib.nullcontext()
        self.lr_decay, self.drift, self.saturation = lr_decay, drift, saturation
        self.gradient_steps, self.update_targets = gradient_steps, update_targets
        self.prioritized = isinstance(batches, PrioritizedMixedReplayBuffer)

    def __call__(self, before: int, frames: int, data) -> dict:
        num_updates = self.cadence(before, frames, data)
        if not num_updates:
            return {}
        alpha = self.alpha_scheduler.alpha
        metrics = self.lr_decay(self.cadence.began_at(before, data)) if self.lr_decay is not None else {}
        if self.prioritized:
            batches, drawn = self._prioritized(num_updates), []
        else:
            with timeit("sample"), self.precision:  # the D reward too, with precision=bf16
                block = self.batches.sample(self.batch_size, teacher_fraction=alpha, num_batches=num_updates)
            metrics[self.reward_tag] = block["next", "reward"].mean()
            batches, drawn = block.unbind(0), None
        last = {}
        for step, batch in enumerate(batches):
            if step == 0 and self.drift is not None:
                self.drift.start(batch)
            if drawn is not None:
                drawn.append(batch.select(("next", "reward"), "is_teacher", "priority_weight"))
            self.gradient_steps += 1
            delayed_step = self.gradient_steps % self.policy_delay == 0
            update_actor = delayed_step and self.gradient_steps >= self.actor_updates_after
            with timeit("update"):
                last.update(self.update(batch, update_actor=update_actor))
                if delayed_step and not update_actor:
                    self.update_targets()
        if drawn is not None:  # and the teacher share the priorities gave
            drawn = torch.stack(drawn)
            metrics[self.reward_tag] = drawn["next", "reward"].mean()
            metrics["sail/teacher_share"] = drawn["is_teacher"].float().mean()
            # PER's weights scale the losses (weight_normalization=count), not the L2 term beside them
            metrics["sail/priority_weight_mean"] = drawn["priority_weight"].mean()
        metrics.update({f"sail/{key}": value for key, value in last.items()})
        if self.drift is not None:
            metrics.update(self.drift.measure())
        if alpha < 1 and self.saturation is not None:  # the batch holds agent rows
            metrics.update(self.saturation(batch))
        return metrics

    @property
    def actor_started(self) -> bool:
        """Whether a step has updated the actor: the first is the first multiple of ``policy_delay``
        from ``actor_updates_after`` (and from step 1) on."""
        first = -(-max(self.actor_updates_after, 1) // self.policy_delay) * self.policy_delay
        return self.gradient_steps >= first

    def _prioritized(self, num_updates: int):
        """One batch per step: each step's new priorities change the next step's draw."""
        for _ in range(num_updates):
            with timeit("sample"), self.precision:
                batch = self.batches.sample(self.batch_size)
            yield batch


def make_td3_block(
    cfg: DictConfig, batches, update, actor, loss, alpha_scheduler, optimizers, *, gradient_steps, target_updater
):
    """The TD3 (or SAC) block of ``cfg``: its cadence, precision, actor lr decay and diagnostics
    (``target_updater``: the targets' Polyak step before the actor starts)."""
    o, td3 = cfg.optim, cfg.algo.learner == "td3"
    decay = o.actor_lr_decay
    return TD3Block(
        batches,
        update,
        cadence=make_cadence(cfg, every_frames=o.train_every_frames, steps=o.updates_per_train),
        alpha_scheduler=alpha_scheduler,
        batch_size=o.batch_size,
        policy_delay=o.policy_delay,
        actor_updates_after=o.actor_updates_after,
        reward_tag="sail/env_reward_mean" if cfg.algo.reward.source == "env" else "sail/d_reward_mean",
        precision=torch.autocast(torch.device(cfg.device).type, dtype=torch.bfloat16, enabled=o.precision == "bf16"),
        lr_decay=None
        if decay is None
        else ActorLRDecay(optimizers["actor"], actor_lr(cfg), rate=decay.rate, every_frames=decay.every_frames),
        drift=ActorDrift(actor, loss) if td3 else None,
        saturation=(lambda batch: actor_saturation(cfg, actor, batch)) if td3 else None,
        gradient_steps=gradient_steps,
        update_targets=target_updater.step,
    )


class PredictorUpdate:
    """SAIL-RND: after each D step, RND's predictor learns the agent's states of the same batch
    (its running observation statistics are the training env's, created at the env's first step)."""

    def __init__(self, rnd, rnd_loss, optimizer) -> None:
        self.rnd, self.rnd_loss, self.optimizer = rnd, rnd_loss, optimizer

    def __call__(self, batch) -> dict:
        self.rnd_loss.obs_rms = self.rnd.obs_rms
        out = self.rnd_loss(batch[~batch["is_teacher"]])
        out["loss_predictor"].backward()
        self.optimizer.step()
        self.optimizer.zero_grad(set_to_none=True)
        return {"rnd/loss_predictor": out["loss_predictor"].detach()}


class DiscriminatorBlock:
    """Algorithm 1's discriminator update: as many D steps as ``cadence`` gives the batch, each on
    ``batch_size`` teacher + ``batch_size`` agent rows (``utils.discriminator_block``); ``after_step``
    runs after each (RND's predictor). A method without a D has no block."""

    def __init__(self, cfg: DictConfig, batches, d_loss, optimizer, *, cadence, batch_size, after_step) -> None:
        self.cfg, self.batches, self.d_loss, self.optimizer = cfg, batches, d_loss, optimizer
        self.cadence, self.batch_size, self.after_step = cadence, batch_size, after_step

    def __call__(self, before: int, frames: int, data) -> dict:
        num_steps = self.cadence(before, frames, data)
        if not num_steps:
            return {}
        with timeit("sample"):
            block = self.batches.sample(2 * self.batch_size, teacher_fraction=0.5, num_batches=num_steps)
        with timeit("discriminator"):
            return discriminator_block(self.cfg, self.d_loss, self.optimizer, block, self.after_step)


def make_learning_blocks(cfg: DictConfig, td3_block: TD3Block, batches, d_loss, optimizers, rnd=None, rnd_loss=None):
    """The batch's learning blocks in ``optim.block_order``: the SAIL authors' TD3 block then D block,
    or Kostrikov et al.'s D block first (each TD3 block then learns from the D just updated). A
    method whose reward is the env's has the TD3 block alone."""
    d = cfg.optim.discriminator
    if cfg.algo.reward.source == "env" or not d.steps:
        return [td3_block]
    d_block = DiscriminatorBlock(
        cfg,
        batches,
        d_loss,
        optimizers["discriminator"],
        cadence=make_cadence(cfg, every_frames=d.every_frames, steps=d.steps),
        batch_size=d.batch_size,
        after_step=PredictorUpdate(rnd, rnd_loss, optimizers["rnd"]) if rnd is not None else None,
    )
    return [d_block, td3_block] if cfg.optim.block_order == "discriminator_first" else [td3_block, d_block]


# ----------------------------------------------------------------------------- evaluation


class Evaluations:
    """Every ``eval.every_frames`` frames: deterministic episodes of the actor ``eval.actor`` names,
    kept in ``run["evals"]`` (``eval/return``, with ``eval/min_return`` and ``eval/below_teacher``:
    :func:`run_utils.evaluation_metrics`), and with ``eval.other_actor`` of every other actor the
    run has (``eval/return_<online|target|average>`` and so on: same seeds, an env each); every
    ``eval.video_every_frames`` frames a video of one episode of the evaluated actor. The
    evaluated actor's (``eval.actor``'s) ``eval/return`` goes to ``best_evaluated``
    (:class:`run_utils.BestEvaluatedPolicy`); the other actors' do not choose it.

    Args:
        actors: the live weights of each actor by name (:func:`run_utils.actor_weights`; ``None``:
            ``actor`` alone, an on-policy learner's).
        envs: ``{"evaluated": env, "others": {actor name: env}}`` (:func:`make_eval_envs`), and
            ``"video"``: a render env with ``video``.
        video: ``video(env, actor, frames)`` records and logs one episode (``None``: no videos).
        best_evaluated: keeps the actors at the best evaluation (``None``: nothing kept).
    """

    def __init__(
        self, cfg: DictConfig, actor, actors, run: dict, teacher_return: float, envs: dict, video, best_evaluated=None
    ) -> None:
        self.cfg, self.actor, self.actors, self.run, self.teacher_return = cfg, actor, actors, run, teacher_return
        self.envs, self.video, self.best_evaluated = envs, video, best_evaluated

    def __call__(self, before: int, frames: int) -> dict:
        cfg, metrics = self.cfg, {}
        if crossings(cfg.eval.every_frames, 0, before, frames):
            metrics.update(
                record_evaluation(
                    self.envs["evaluated"], self.actor, self.actors, cfg, self.run, frames, self.teacher_return
                )
            )
            if self.best_evaluated is not None:
                self.best_evaluated.keep(metrics["eval/return"], frames)
            for name, env in self.envs["others"].items():
                weights = None if name == "online" else self.actors[name]
                returns = actor_returns(env, self.actor, weights, cfg.eval.episodes, cfg.env.max_episode_steps)
                metrics.update(evaluation_metrics(returns, self.teacher_return, f"_{name}"))
        if crossings(cfg.eval.video_every_frames, 0, before, frames):  # of the evaluated actor
            weights = None if cfg.eval.actor == "online" else self.actors[str(cfg.eval.actor)]
            with weights_in(self.actor, weights):
                self.video(self.envs["video"], self.actor, frames)
        return metrics


def make_eval_envs(cfg: DictConfig, make_eval_env) -> dict:
    """The evaluations' envs (``make_eval_env(cfg, seed, episodes)``, :func:`utils.make_eval_env`),
    ``{"evaluated": env, "others": {actor name: env}}``: with ``eval.other_actor``, each other
    actor's episodes start where the evaluated one's do (same seed, an env of its own)."""
    others = [name for name in actor_names(cfg) if name != cfg.eval.actor] if cfg.eval.other_actor else []
    seed, episodes = cfg.seed + 10_000, cfg.eval.episodes
    return {
        "evaluated": make_eval_env(cfg, seed, episodes),
        "others": {name: make_eval_env(cfg, seed, episodes) for name in others},
    }


def make_evaluations(
    cfg: DictConfig, envs: dict, actor, actors, run: dict, teacher_return: float, loggers, run_dir, best_evaluated=None
):
    """The evaluations of ``cfg`` on ``envs`` (:func:`make_eval_envs`), keeping the best in
    ``best_evaluated``. With ``eval.video_every_frames`` the render env is built here, before
    training: a missing GL backend fails now."""
    video = None
    if cfg.eval.video_every_frames:
        envs = {**envs, "video": make_render_env(cfg, cfg.seed + 30_000, cfg.eval.video_size)}

        def video(env, actor, frames):
            log_video(loggers, env, actor, cfg, run_dir, frames)

    return Evaluations(cfg, actor, actors, run, teacher_return, envs, video, best_evaluated)
