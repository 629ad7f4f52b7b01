"""Schedules SAIL's teacher-sampling coefficient ``alpha`` on a loss module.

SAIL mixes teacher and self-generated transitions with a coefficient ``alpha``
(``d_mix = alpha d_T + (1 - alpha) d_B``). The paper initialises ``alpha = 0.5`` and
"anneals it to zero" once the agent reaches teacher-level performance; the authors' code
(task ``...-adaptive-dynamic``) implements that as a one-time hard switch: ``alpha`` drops
to 0 for good as soon as the first agent trajectory is promoted into the teacher buffer.
A ``LinearSchedule(3e5, 0.5 -> 0)`` is built there but never used.

:class:`AlphaScheduler` drives ``loss.alpha`` (a schedulable buffer of
:class:`~torchrl_sail.SAILLoss`) the way TorchRL's target-network updaters drive target
parameters: it is built on the loss and stepped from the training loop.
"""
from __future__ import annotations

from typing import Any

from torchrl_sail.objectives.sail import _check_alpha

__all__ = ["AlphaScheduler"]

_MODES = ("dynamic", "linear", "constant")


def _check_count(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError(
            f"AlphaScheduler.step: {name} must be a non-negative int, got {value!r} "
            f"({type(value).__name__})."
        )
    if value < 0:
        raise ValueError(
            f"AlphaScheduler.step: {name} must be non-negative, got {value}."
        )
    return value


class AlphaScheduler:
    """Updates ``loss.alpha`` (the teacher share of SAIL's batches) during training.

    Three modes:

    - ``"dynamic"`` (default, the authors' code): ``alpha = initial`` until the first
      agent trajectory is promoted into the teacher buffer, then ``final`` forever. The
      switch happens on the first :meth:`step` that sees ``num_promoted > 0`` and is
      never undone; :attr:`switched_at_frame` records the ``frames`` of that call.
    - ``"linear"``: ``alpha = initial + (final - initial) * min(frames / anneal_frames, 1)``,
      counted from frame 0 like the authors' unused ``LinearSchedule`` (the paper's
      "anneal" wording). Promotions are ignored.
    - ``"constant"``: ``alpha = initial`` forever (ablations: "SAIL w/o LfD" uses
      ``initial=0``, "SAIL w/o adaptation" keeps ``0.5``). ``final`` is ignored.

    The scheduler writes ``loss.alpha = initial`` when it is built, so the loss starts from
    the schedule's first value whatever it was constructed with.

    Args:
        loss (LossModule): the loss whose ``alpha`` attribute is driven, typically a
            :class:`~torchrl_sail.SAILLoss` (any object with a settable ``alpha`` works).

    Keyword Args:
        mode (str, optional): ``"dynamic"``, ``"linear"`` or ``"constant"``.
            Defaults to ``"dynamic"``.
        initial (float, optional): starting value, in ``[0, 1]``. Defaults to ``0.5``.
        final (float, optional): value after the switch / at the end of the anneal, in
            ``[0, 1]``. Defaults to ``0.0``.
        anneal_frames (int, optional): number of env frames of the linear anneal; required
            (positive) for ``mode="linear"`` and must be ``None`` otherwise.

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
        >>> loss.alpha
        0.0
        >>> lin = AlphaScheduler(loss, mode="linear", anneal_frames=300_000)
        >>> lin.step(frames=150_000, num_promoted=0)
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
        if not hasattr(loss, "alpha"):
            raise TypeError(
                f"AlphaScheduler: {type(loss).__name__} has no 'alpha' attribute to "
                f"schedule; pass a torchrl_sail.SAILLoss."
            )
        if mode not in _MODES:
            raise ValueError(
                f"AlphaScheduler: mode must be one of {_MODES}, got {mode!r}."
            )
        initial = _check_alpha(initial, where="AlphaScheduler(initial=...)")
        final = _check_alpha(final, where="AlphaScheduler(final=...)")
        if mode == "linear":
            if (
                anneal_frames is None
                or isinstance(anneal_frames, bool)
                or not isinstance(anneal_frames, int)
                or anneal_frames <= 0
            ):
                raise ValueError(
                    f"AlphaScheduler: mode='linear' needs anneal_frames, a positive int "
                    f"number of env frames, got {anneal_frames!r}."
                )
        elif anneal_frames is not None:
            raise ValueError(
                f"AlphaScheduler: anneal_frames={anneal_frames!r} is only used by "
                f"mode='linear' (got mode={mode!r}); leave it None."
            )
        self.loss = loss
        self.mode = mode
        self.initial = initial
        self.final = final
        self.anneal_frames = anneal_frames
        self._alpha = initial
        self._switched_at_frame: int | None = None
        self._last_frames = 0
        self._last_num_promoted = 0
        self.loss.alpha = initial

    @property
    def alpha(self) -> float:
        """The current value (the one last written to ``loss.alpha``)."""
        return self._alpha

    @property
    def switched_at_frame(self) -> int | None:
        """``frames`` at the dynamic switch, ``None`` before it (and in other modes)."""
        return self._switched_at_frame

    def _value(self, frames: int, num_promoted: int) -> float:
        if self.mode == "constant":
            return self.initial
        if self.mode == "linear":
            progress = min(frames / self.anneal_frames, 1.0)
            return self.initial + (self.final - self.initial) * progress
        if self._switched_at_frame is None and num_promoted > 0:
            self._switched_at_frame = frames
        return self.initial if self._switched_at_frame is None else self.final

    def step(self, *, frames: int, num_promoted: int) -> float:
        """Update ``loss.alpha`` and return the new value.

        Keyword Args:
            frames (int): total env frames collected so far (cumulative, non-decreasing).
            num_promoted (int): total number of agent trajectories promoted into the
                teacher buffer so far (cumulative, non-decreasing).

        Returns:
            the new ``alpha`` (a Python float).
        """
        frames = _check_count("frames", frames)
        num_promoted = _check_count("num_promoted", num_promoted)
        # Both are running totals: a decrease means per-batch counts are being passed,
        # which would make the linear schedule and switched_at_frame silently wrong.
        if frames < self._last_frames:
            raise ValueError(
                f"AlphaScheduler.step: frames must be the cumulative env frame count "
                f"(non-decreasing), got {frames} after {self._last_frames}."
            )
        if num_promoted < self._last_num_promoted:
            raise ValueError(
                f"AlphaScheduler.step: num_promoted must be the cumulative number of "
                f"promoted trajectories (non-decreasing), got {num_promoted} after "
                f"{self._last_num_promoted}."
            )
        self._last_frames = frames
        self._last_num_promoted = num_promoted
        self._alpha = self._value(frames, num_promoted)
        self.loss.alpha = self._alpha
        return self._alpha

    def state_dict(self) -> dict[str, Any]:
        """Return the configuration and progress as a plain (``torch.save``-able) dict."""
        return {
            "mode": self.mode,
            "initial": self.initial,
            "final": self.final,
            "anneal_frames": self.anneal_frames,
            "alpha": self._alpha,
            "switched_at_frame": self._switched_at_frame,
            "last_frames": self._last_frames,
            "last_num_promoted": self._last_num_promoted,
        }

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        """Restore progress saved by :meth:`state_dict` and write ``alpha`` to the loss.

        Args:
            state_dict (dict): the output of :meth:`state_dict` of a scheduler with the
                same configuration (``mode``, ``initial``, ``final``, ``anneal_frames``).
        """
        missing = [k for k in self.state_dict() if k not in state_dict]
        if missing:
            raise KeyError(
                f"AlphaScheduler.load_state_dict: missing entries {missing}; expected "
                f"the output of AlphaScheduler.state_dict()."
            )
        for key in ("mode", "initial", "final", "anneal_frames"):
            if state_dict[key] != getattr(self, key):
                raise ValueError(
                    f"AlphaScheduler.load_state_dict: saved {key}={state_dict[key]!r} "
                    f"differs from this scheduler's {key}={getattr(self, key)!r}; build "
                    f"the scheduler with the same configuration before loading."
                )
        alpha = _check_alpha(state_dict["alpha"], where="AlphaScheduler.load_state_dict")
        switched = state_dict["switched_at_frame"]
        self._switched_at_frame = None if switched is None else int(switched)
        self._last_frames = int(state_dict["last_frames"])
        self._last_num_promoted = int(state_dict["last_num_promoted"])
        self._alpha = alpha
        self.loss.alpha = alpha

    def __repr__(self) -> str:
        extra = "" if self.anneal_frames is None else f", anneal_frames={self.anneal_frames}"
        return (
            f"{type(self).__name__}(mode={self.mode!r}, initial={self.initial}, "
            f"final={self.final}{extra}, alpha={self._alpha}, "
            f"switched_at_frame={self._switched_at_frame})"
        )
