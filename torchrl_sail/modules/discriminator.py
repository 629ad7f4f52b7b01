"""The SAIL state-action discriminator D(s, a) and its running observation normaliser.

SAIL (like GAIL/DAC) trains a binary classifier that separates teacher transitions
(label 1) from agent transitions (label 0). Its logit gives the imitation
reward the critic is trained on (see
:class:`~torchrl_sail.DiscriminatorReward`); it is trained by
:class:`~torchrl_sail.DiscriminatorLoss`.

This module follows the authors' ``DiscriminatorCalssifier``
(``stable_baselines/gail/adversary.py``): observations are normalised with running
statistics (same prior and std floor as the MPI ``RunningMeanStd`` of
stable-baselines), actions are not normalised, the two are concatenated and fed to a
256-256 tanh MLP with Glorot-uniform weights and zero biases that outputs one logit.

Three layers, from the inside out:

- :class:`RunningObsNorm`: running mean/std, updated explicitly (only the loss does).
- :class:`DiscriminatorNet`: a plain ``nn.Module`` ``(observation, action) -> logit``
  whose forward is a pure function (it never updates the normaliser), so it can run
  under ``torch.no_grad()`` or ``torch.compile``. ``features``/``head`` are exposed
  separately because the gradient penalty is taken in the normalised feature space.
- :class:`Discriminator`: the :class:`~tensordict.nn.TensorDictModule` face
  (``"observation"``, ``"action"`` -> ``"d_logit"``), like TorchRL's ``ValueOperator``.
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import contextmanager

import torch
from tensordict.nn import TensorDictModule
from tensordict.utils import NestedKey
from torch import nn
from torchrl.modules import MLP

from torchrl_sail.modules.init import check_linear_init, reset_linears

__all__ = ["Discriminator", "DiscriminatorNet", "RunningObsNorm"]


class RunningObsNorm(nn.Module):
    """Running observation normaliser with the statistics of the SAIL authors' code.

    Keeps float64 running sums (``sum``, ``sumsq``, ``count``) initialised to a small
    prior, exactly like stable-baselines' MPI ``RunningMeanStd`` used by the SAIL
    discriminator:

    .. math::

        \\mu = \\frac{\\text{sum}}{\\text{count}}, \\qquad
        \\sigma = \\sqrt{\\max\\left(\\frac{\\text{sumsq}}{\\text{count}} - \\mu^2,\\
        \\text{min\\_var}\\right)}

    with ``sum = 0``, ``sumsq = epsilon``, ``count = epsilon`` before any update, so
    the initial statistics are ``mean = 0`` and ``std = 1``. With the default
    ``min_var=1e-2`` the std is floored at 0.1. :meth:`forward` returns
    ``(x - mean) / std`` without clipping (the authors do not clip the discriminator
    inputs).

    The statistics are buffers, so they are saved in ``state_dict()`` and follow
    ``.to(device)``. They only change through :meth:`update`, never in
    :meth:`forward`.

    Args:
        shape (int or sequence of int): the trailing (feature) shape of the
            observations, e.g. ``obs_dim``.

    Keyword Args:
        epsilon (float, optional): prior value of ``sumsq`` and ``count``.
            Defaults to ``1e-2`` (the authors' value).
        min_var (float, optional): floor of the variance. Defaults to ``1e-2``
            (std floored at ``0.1``, the authors' value).

    Examples:
        >>> import torch
        >>> from torchrl_sail import RunningObsNorm
        >>> norm = RunningObsNorm(2)
        >>> norm.update(torch.tensor([[1.0, 5.0], [3.0, 5.0]]))
        >>> [round(v, 4) for v in norm.mean.tolist()]
        [1.99, 4.9751]
        >>> [round(v, 4) for v in norm.std.tolist()]
        [1.0099, 0.3588]
        >>> norm(torch.tensor([[2.0, 5.0]])).dtype
        torch.float32
    """

    sum: torch.Tensor
    sumsq: torch.Tensor
    count: torch.Tensor

    def __init__(
        self,
        shape: int | Sequence[int],
        *,
        epsilon: float = 1e-2,
        min_var: float = 1e-2,
    ) -> None:
        super().__init__()
        shape = (shape,) if isinstance(shape, int) else tuple(shape)
        if epsilon <= 0 or min_var < 0:
            # epsilon is the prior count (0 gives NaN statistics), min_var the variance floor
            raise ValueError(
                f"RunningObsNorm needs epsilon > 0 and min_var >= 0, got epsilon={epsilon} and min_var={min_var}."
            )
        self.shape = torch.Size(shape)
        self.min_var = float(min_var)
        self.register_buffer("sum", torch.zeros(shape, dtype=torch.float64))
        self.register_buffer("sumsq", torch.full(shape, epsilon, dtype=torch.float64))
        self.register_buffer("count", torch.tensor(epsilon, dtype=torch.float64))

    @property
    def mean(self) -> torch.Tensor:
        """The running mean (float64)."""
        return self.sum / self.count

    @property
    def std(self) -> torch.Tensor:
        """The running standard deviation (float64), floored at ``sqrt(min_var)``."""
        mean = self.mean
        return (self.sumsq / self.count - mean.square()).clamp_min(self.min_var).sqrt()

    @torch.no_grad()
    def update(self, x: torch.Tensor) -> None:
        """Adds a batch of observations to the running statistics.

        Args:
            x (torch.Tensor): observations of shape ``[*batch, *shape]``; every leading
                dimension counts as a batch dimension.
        """
        x = x.detach().reshape(-1, *self.shape).to(torch.float64)
        self.sum.add_(x.sum(0))
        self.sumsq.add_(x.square().sum(0))
        self.count.add_(x.shape[0])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Normalises ``x`` with the current statistics, in ``x``'s dtype.

        Args:
            x (torch.Tensor): observations of shape ``[*batch, *shape]``.
        """
        mean = self.mean.to(x.dtype)
        std = self.std.to(x.dtype)
        return (x - mean) / std

    def extra_repr(self) -> str:
        return f"shape={tuple(self.shape)}, min_var={self.min_var}"


class DiscriminatorNet(nn.Module):
    """State-action discriminator ``D(s, a)`` returning a logit (authors' architecture).

    ``logit = MLP([normalise(s), a])``, where ``normalise`` is a
    :class:`RunningObsNorm` (or the identity with ``normalize_observations=False``)
    and the MLP is a :class:`torchrl.modules.MLP` with ``num_cells`` hidden units, the
    given activation and one output. ``sigmoid(logit)`` is the probability that
    ``(s, a)`` comes from the teacher.

    Following the authors' ``tf.contrib.layers.fully_connected`` defaults, every linear
    layer is re-initialised with Glorot/Xavier-uniform weights and zero biases
    (:meth:`reset_parameters`; ``init="orthogonal"``: orthogonal weights and zero biases, as
    Kostrikov et al.'s DAC release; ``init="torch"`` keeps ``nn.Linear``'s own init).

    :meth:`forward` never updates the normaliser: only
    :class:`~torchrl_sail.DiscriminatorLoss` does, explicitly. The forward is therefore
    a pure function of the weights and statistics, safe under ``torch.no_grad()``
    (reward computation) or ``torch.compile``.

    Args:
        observation_dim (int): size of the observation vector (including the time
            feature, if any).
        action_dim (int): size of the action vector.

    Keyword Args:
        num_cells (sequence of int, optional): hidden layer sizes. Defaults to
            ``(256, 256)``.
        activation_class (type of nn.Module, optional): hidden activation. Defaults to
            :class:`~torch.nn.Tanh`.
        normalize_observations (bool, optional): normalise observations with a
            :class:`RunningObsNorm` (attribute ``obs_norm``). If ``False``,
            ``obs_norm`` is ``None`` and observations are used as they are. Defaults
            to ``True``.
        spectral_norm (bool, optional): divide every linear layer's weight by its largest
            singular value (Miyato et al.'s spectral normalisation, torch's
            ``nn.utils.parametrizations.spectral_norm``), which bounds how steep the logit can
            get and so how fast D saturates. The singular vectors (buffers, saved with the
            weights) advance by one power iteration per training step of
            :class:`~torchrl_sail.DiscriminatorLoss` (:meth:`spectral_norm_iteration`), never in a
            plain forward, which stays pure. Not the authors' (they have none). Defaults to
            ``False``.
        init (str, optional): the linear layers' weights: ``"xavier"`` (Glorot-uniform, the SAIL
            authors') or ``"orthogonal"`` (gain 1, Kostrikov et al.'s DAC release), biases zero; or
            ``"torch"``, ``nn.Linear``'s own init (TorchRL's GAIL example). Defaults to ``"xavier"``.

    Examples:
        >>> import torch
        >>> from torchrl_sail import DiscriminatorNet
        >>> net = DiscriminatorNet(3, 1, num_cells=(8, 8))
        >>> obs, act = torch.randn(5, 3), torch.rand(5, 1)
        >>> net.features(obs, act).shape
        torch.Size([5, 4])
        >>> net(obs, act).shape
        torch.Size([5, 1])
        >>> bool((net(obs, act) == net.head(net.features(obs, act))).all())
        True
    """

    def __init__(
        self,
        observation_dim: int,
        action_dim: int,
        *,
        num_cells: Sequence[int] = (256, 256),
        activation_class: type[nn.Module] = nn.Tanh,
        normalize_observations: bool = True,
        spectral_norm: bool = False,
        init: str = "xavier",
    ) -> None:
        super().__init__()
        check_linear_init(init)
        self.init = init
        self.observation_dim = observation_dim
        self.action_dim = action_dim
        self.obs_norm = RunningObsNorm(observation_dim) if normalize_observations else None
        self.mlp = MLP(
            in_features=observation_dim + action_dim,
            out_features=1,
            num_cells=list(num_cells),
            activation_class=activation_class,
        )
        self.spectral_norm = spectral_norm
        self.reset_parameters()

    def _linears(self) -> list[nn.Linear]:
        return [layer for layer in self.mlp.modules() if isinstance(layer, nn.Linear)]

    def _spectral_norms(self) -> list[nn.Module]:
        return [layer.parametrizations.weight for layer in self._linears() if hasattr(layer, "parametrizations")]

    def reset_parameters(self) -> None:
        """Re-initialises the MLP by ``init``: Glorot-uniform (the authors') or orthogonal weights with zero
        biases, or ``nn.Linear``'s own init (``"torch"``).

        With ``spectral_norm``, the normalisation is registered again on the new weights (the
        same parameters), with singular vectors estimated afresh (15 power iterations). The
        normaliser statistics are left untouched.
        """
        with torch.no_grad():
            for layer in self._linears():
                if hasattr(layer, "parametrizations"):
                    nn.utils.parametrize.remove_parametrizations(layer, "weight", leave_parametrized=False)
                reset_linears(layer, self.init)
                if self.spectral_norm:
                    nn.utils.parametrizations.spectral_norm(layer)
        self.train(self.training)  # the new normalisations do not iterate in a forward

    def train(self, mode: bool = True) -> DiscriminatorNet:
        """Sets the training mode; the spectral normalisations stay in eval mode (no power iteration
        in a forward, see :meth:`spectral_norm_iteration`)."""
        super().train(mode)
        for norm in self._spectral_norms():
            norm.eval()
        return self

    @contextmanager
    def spectral_norm_iteration(self):
        """Within it, each forward advances the spectral normalisations' singular vectors by one power
        iteration (what torch's ``spectral_norm`` does in training mode). :class:`~torchrl_sail.DiscriminatorLoss`
        uses it once per training step. A no-op without ``spectral_norm``."""
        norms = self._spectral_norms()
        for norm in norms:
            norm.train()
        try:
            yield
        finally:
            for norm in norms:
                norm.eval()

    @property
    def dtype(self) -> torch.dtype:
        """The dtype of the MLP parameters (the dtype observations must have)."""
        return next(self.mlp.parameters()).dtype

    def features(self, observation: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """Returns the MLP input ``concat(normalise(observation), action)``.

        Observations are not cast: they must have the parameters' dtype (:attr:`dtype`;
        add ``DoubleToFloat()`` to a float64 MuJoCo env and its demonstrations).

        Args:
            observation (torch.Tensor): ``[*batch, observation_dim]``.
            action (torch.Tensor): ``[*batch, action_dim]``.
        """
        if self.obs_norm is not None:
            observation = self.obs_norm(observation)
        return torch.cat([observation, action.to(observation.dtype)], dim=-1)

    def head(self, features: torch.Tensor) -> torch.Tensor:
        """Maps features (see :meth:`features`) to logits of shape ``[*batch, 1]``.

        Args:
            features (torch.Tensor): ``[*batch, observation_dim + action_dim]``.
        """
        return self.mlp(features)

    def forward(self, observation: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """Returns the logit ``[*batch, 1]`` of ``P(teacher | observation, action)``.

        Args:
            observation (torch.Tensor): ``[*batch, observation_dim]``.
            action (torch.Tensor): ``[*batch, action_dim]``.
        """
        return self.head(self.features(observation, action))


class Discriminator(TensorDictModule):
    """TensorDict face of :class:`DiscriminatorNet`: reads ``(s, a)``, writes the logit.

    Built like TorchRL's :class:`~torchrl.modules.ValueOperator`: it creates the
    :class:`DiscriminatorNet` and wraps it in a
    :class:`~tensordict.nn.TensorDictModule`. The same instance is meant to be shared by
    :class:`~torchrl_sail.DiscriminatorLoss` (which trains it) and
    :class:`~torchrl_sail.DiscriminatorReward` (which turns its logit into a reward).

    Args:
        observation_dim (int): size of the observation vector.
        action_dim (int): size of the action vector.

    Keyword Args:
        in_keys (sequence of NestedKey, optional): the observation and action keys, in
            that order. Defaults to ``("observation", "action")``.
        out_key (NestedKey, optional): where the logit is written. Defaults to
            ``"d_logit"``.
        **net_kwargs: forwarded to :class:`DiscriminatorNet` (``num_cells``,
            ``activation_class``, ``normalize_observations``, ``spectral_norm``, ``init``).

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import Discriminator
        >>> disc = Discriminator(3, 2, num_cells=(16, 16))
        >>> td = TensorDict(observation=torch.randn(4, 3), action=torch.rand(4, 2), batch_size=[4])
        >>> disc(td)["d_logit"].shape
        torch.Size([4, 1])
        >>> type(disc.net).__name__
        'DiscriminatorNet'
    """

    def __init__(
        self,
        observation_dim: int,
        action_dim: int,
        *,
        in_keys: Sequence[NestedKey] = ("observation", "action"),
        out_key: NestedKey = "d_logit",
        **net_kwargs,
    ) -> None:
        net = DiscriminatorNet(observation_dim, action_dim, **net_kwargs)
        super().__init__(module=net, in_keys=list(in_keys), out_keys=[out_key])

    @property
    def net(self) -> DiscriminatorNet:
        """The wrapped :class:`DiscriminatorNet`."""
        return self.module
