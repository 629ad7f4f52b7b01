"""Stop a training run at its first non-finite loss or parameter, checked at the logging cadence."""

from __future__ import annotations

from collections.abc import Mapping

import torch
from torch import nn

__all__ = ["DivergenceCheck", "DivergenceError"]


class DivergenceError(FloatingPointError):
    """A loss, a logged tensor or a parameter of a run became NaN or infinite.

    Attributes:
        frame (int): the frame (or step) count at which the check found it.
        quantities (list[str]): the names of the non-finite quantities, losses first.
    """

    def __init__(self, message: str, *, frame: int, quantities: list[str]) -> None:
        super().__init__(message)
        self.frame = frame
        self.quantities = quantities


class DivergenceCheck:
    """Checks the tensors a loop logs and the floating-point parameters and buffers of its modules.

    A non-finite critic or discriminator loss does not stop training by itself: the NaN spreads
    into the parameters and every later update, and a loss filtered out of the logs hides it.
    Call the check where the loop already reads its metrics back (the logging cadence) and
    before every checkpoint: on the finite path it costs one ``isfinite().all()`` per tensor
    and a single host sync, never one per gradient step. On a non-finite value it raises
    :class:`DivergenceError` naming every offending quantity and the frame, before anything
    non-finite is written, so the last checkpoint on disk stays the last good one.

    Only tensor-valued metrics are checked: plain Python numbers in a metrics dict are the
    loop's bookkeeping (e.g. SAIL's promotion threshold, ``-inf`` until its window fills).

    Args:
        modules (Mapping[str, nn.Module]): the modules whose parameters and floating-point
            buffers to check (the loss holds the actor, critics and target networks), read
            at every call.
        unit (str, optional): what the loop counts, named in the error. Default: ``"frame"``
            (an offline loop counts gradient steps).

    Examples:
        >>> import torch
        >>> from torch import nn
        >>> from torchrl_sail import DivergenceCheck, DivergenceError
        >>> critic = nn.Linear(3, 1)
        >>> check = DivergenceCheck({"critic": critic})
        >>> check({"loss_qvalue": torch.tensor(0.5)}, frame=1000)  # finite: returns None
        >>> with torch.no_grad():
        ...     critic.weight[0, 1] = float("nan")
        >>> try:
        ...     check({"loss_qvalue": torch.tensor(float("inf"))}, frame=2000)
        ... except DivergenceError as err:
        ...     print(err.quantities, err.frame)
        ['loss_qvalue', 'critic.weight'] 2000
    """

    def __init__(self, modules: Mapping[str, nn.Module], *, unit: str = "frame") -> None:
        for prefix, module in modules.items():
            if not isinstance(module, nn.Module):
                raise TypeError(f"DivergenceCheck: modules[{prefix!r}] is a {type(module).__name__}, not an nn.Module")
        self.modules = dict(modules)
        self.unit = unit

    def named_tensors(self) -> dict[str, torch.Tensor]:
        """The floating-point parameters and buffers, read at each call: state created after the check
        (e.g. running statistics made at an env's first step) is checked too."""
        tensors, seen = {}, set()
        for prefix, module in self.modules.items():
            for name, tensor in [*module.named_parameters(), *module.named_buffers()]:
                if tensor.is_floating_point() and id(tensor) not in seen:
                    seen.add(id(tensor))
                    tensors[f"{prefix}.{name}"] = tensor
        return tensors

    @torch.no_grad()
    def __call__(self, metrics: Mapping[str, object], *, frame: int, checkpoint: str | None = None) -> None:
        """Raises :class:`DivergenceError` if a tensor of ``metrics`` or a parameter is not finite.

        Args:
            metrics: the loop's metrics (tensors are checked, other values skipped).
            frame: the frame count, named in the error.
            checkpoint: where the last good checkpoint is, named in the error with what to do.
        """
        logged = {key: value.detach() for key, value in metrics.items() if torch.is_tensor(value)}
        tensors = {**logged, **self.named_tensors()}
        if not tensors:
            return
        # One flag per tensor (exact: no norm that overflows on large finite values), gathered on
        # one device, then a single host sync.
        device = next(iter(tensors.values())).device
        flags = torch.stack([tensor.isfinite().all().to(device, non_blocking=True) for tensor in tensors.values()])
        if bool(flags.all()):
            return
        bad = [name for name, ok in zip(tensors, flags.tolist(), strict=True) if not ok]  # logged tensors come first
        shown = [f"{key}={logged[key].float().reshape(-1)[0].item():g}" if key in logged else key for key in bad[:8]]
        more = f" and {len(bad) - 8} more" if len(bad) > 8 else ""
        where = (
            (
                f" Nothing was saved after the last good checkpoint ({checkpoint}): inspect it, or continue it "
                f"with other settings (e.g. a lower learning rate) and resume=true."
            )
            if checkpoint
            else ""
        )
        raise DivergenceError(
            f"non-finite value at {self.unit} {frame}: {', '.join(shown)}{more} (losses and logged tensors first, "
            f"then parameters).{where}",
            frame=frame,
            quantities=bad,
        )
