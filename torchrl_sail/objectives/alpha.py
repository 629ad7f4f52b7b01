"""Schedules SAIL's teacher share ``alpha`` on a loss module.

The paper starts from ``alpha = 0.5`` and "anneals it to zero" once the agent reaches the
teacher's level; the authors' code (task ``...-adaptive-dynamic``) drops it to 0 for good at
the first agent trajectory promoted into the teacher buffer (its ``LinearSchedule`` is built
but never used). :class:`AlphaScheduler` drives ``loss.alpha`` the way TorchRL's target
updaters drive target parameters: built on the loss, stepped from the training loop.
"""

from __future__ import annotations

from typing import Any

__all__ = ["AlphaScheduler"]


class AlphaScheduler:
    """Updates ``loss.alpha`` (the teacher share of SAIL's batches) during training.

    - ``"dynamic"`` (default, the authors' code): ``initial`` until the first agent
      trajectory is promoted, then ``final`` forever; :attr:`switched_at_frame` records the
      ``frames`` of the :meth:`step` that saw ``num_promoted > 0`` first.
    - ``"linear"``: ``initial + (final - initial) * min(frames / anneal_frames, 1)``, from
      frame 0 (the paper's "anneal"). Promotions are ignored.
    - ``"constant"``: ``initial`` forever (ablations: "SAIL w/o LfD" uses ``initial=0``).

    The scheduler writes ``loss.alpha = initial`` when built. :meth:`step` takes running
    totals (frames collected, trajectories promoted), not per-batch counts.

    Args:
        loss (LossModule): the loss whose ``alpha`` is driven, e.g. a
            :class:`~torchrl_sail.SAILLoss` (any object with a settable ``alpha``).

    Keyword Args:
        mode (str, optional): ``"dynamic"``, ``"linear"`` or ``"constant"``. Defaults to
            ``"dynamic"``.
        initial (float, optional): starting value, in ``[0, 1]``. Defaults to ``0.5``.
        final (float, optional): value after the switch or at the end of the anneal, in
            ``[0, 1]``. Defaults to ``0.0``.
        anneal_frames (int, optional): length of the linear anneal in env frames; required
            by ``mode="linear"``.

    Examples:
        >>> from types import SimpleNamespace
        >>> from torchrl_sail import AlphaScheduler
        >>> loss = SimpleNamespace(alpha=1.0)  # stands in for a SAILLoss
        >>> sched = AlphaScheduler(loss)  # dynamic, 0.5 -> 0 at the first promotion
        >>> loss.alpha
        0.5
        >>> sched.step(frames=10_000, num_promoted=0), sched.switched_at_frame
        (0.5, None)
        >>> sched.step(frames=12_000, num_promoted=1), sched.switched_at_frame
        (0.0, 12000)
        >>> AlphaScheduler(loss, mode="linear", anneal_frames=300_000).step(
        ...     frames=150_000, num_promoted=0)
        0.25
    """

    def __init__(
        self,
        loss,
        *,
        mode: str = "dynamic",
        initial: float = 0.5,
        final: float = 0.0,
        anneal_frames: int | None = None,
    ) -> None:
        if mode not in ("dynamic", "linear", "constant"):
            raise ValueError(f"mode must be 'dynamic', 'linear' or 'constant', got {mode!r}.")
        if not (0.0 <= initial <= 1.0 and 0.0 <= final <= 1.0):
            raise ValueError(f"initial and final must be in [0, 1], got {initial}, {final}.")
        if mode == "linear" and not (anneal_frames or 0) > 0:
            raise ValueError(f"mode='linear' needs anneal_frames > 0, got {anneal_frames!r}.")
        self.loss = loss
        self.mode = mode
        self.initial = initial
        self.final = final
        self.anneal_frames = anneal_frames
        self.alpha = initial
        self.switched_at_frame: int | None = None
        self.loss.alpha = initial

    def step(self, *, frames: int, num_promoted: int) -> float:
        """Writes the value for this point of training to ``loss.alpha`` and returns it.

        Keyword Args:
            frames (int): env frames collected so far.
            num_promoted (int): agent trajectories promoted into the teacher buffer so far.
        """
        if self.mode == "linear":
            progress = min(frames / self.anneal_frames, 1.0)
            self.alpha = self.initial + (self.final - self.initial) * progress
        elif self.mode == "dynamic":
            if self.switched_at_frame is None and num_promoted > 0:
                self.switched_at_frame = frames
            self.alpha = self.initial if self.switched_at_frame is None else self.final
        self.loss.alpha = self.alpha
        return self.alpha

    def state_dict(self) -> dict[str, Any]:
        return {"alpha": self.alpha, "switched_at_frame": self.switched_at_frame}

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        self.alpha = state_dict["alpha"]
        self.switched_at_frame = state_dict["switched_at_frame"]
        self.loss.alpha = self.alpha

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(mode={self.mode!r}, initial={self.initial}, "
            f"final={self.final}, alpha={self.alpha}, switched_at_frame={self.switched_at_frame})"
        )
