"""The linear layers' weight init, by name: the SAIL authors', Kostrikov et al.'s DAC release, or PyTorch's own."""

from __future__ import annotations

import torch
from torch import nn

# xavier: Glorot-uniform (tf's dense / fully_connected default, the SAIL authors'); orthogonal (gain 1,
# DAC's release); torch: nn.Linear's own reset_parameters (Kaiming-uniform weights, uniform biases)
_WEIGHT_INITS = {"xavier": nn.init.xavier_uniform_, "orthogonal": nn.init.orthogonal_, "torch": None}
LINEAR_INITS = tuple(_WEIGHT_INITS)


def check_linear_init(init: str) -> None:
    """Raises ``ValueError`` naming ``init`` unless it is one of :data:`LINEAR_INITS`."""
    if init not in _WEIGHT_INITS:
        raise ValueError(f"init={init!r}: must be one of {sorted(_WEIGHT_INITS)}")


def reset_linears(module: nn.Module, init: str) -> None:
    """Re-initialises every ``nn.Linear`` in ``module``: ``"xavier"`` or ``"orthogonal"`` weights with
    zero biases, or (``"torch"``) each layer's own ``reset_parameters()``.

    Args:
        module (nn.Module): the network; its linear layers are changed in place.
        init (str): one of :data:`LINEAR_INITS`.

    Examples:
        >>> import torch
        >>> from torchrl.modules import MLP
        >>> from torchrl_sail.modules.init import reset_linears
        >>> net = MLP(in_features=4, out_features=1, num_cells=[8])
        >>> reset_linears(net, "xavier")
        >>> bool((net[0].bias == 0).all()) and net[0].weight.abs().max().item() <= (6 / (4 + 8)) ** 0.5
        True
    """
    check_linear_init(init)
    weight_init = _WEIGHT_INITS[init]
    with torch.no_grad():
        for layer in module.modules():
            if not isinstance(layer, nn.Linear):
                continue
            if weight_init is None:
                layer.reset_parameters()
                continue
            weight_init(layer.weight)
            if layer.bias is not None:
                nn.init.zeros_(layer.bias)
