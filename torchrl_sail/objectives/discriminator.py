"""Discriminator loss of SAIL: BCE + Bernoulli-entropy bonus + gradient penalty.

SAIL trains its discriminator ``D(s, a)`` to tell teacher transitions (label 1) from
agent transitions (label 0); ``-log(1 - D)`` is then the critic's reward
(:class:`~torchrl_sail.DiscriminatorReward`). This module reproduces the loss of the
authors' ``DiscriminatorCalssifier`` (``stable_baselines/gail/adversary.py``):

.. math::

    L = \\overline{\\mathrm{BCE}(\\ell_{agent}, 0)} + \\overline{\\mathrm{BCE}(\\ell_{teacher}, 1)}
        - c_{ent}\\, \\overline{H(\\ell)} + c_{gp}\\, \\mathrm{GP}

on one *tagged* mixed batch (``"is_teacher"``), and keeps the running observation
normaliser of the discriminator up to date, as the authors do before every
discriminator minibatch.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, dispatch
from tensordict.utils import NestedKey
from torchrl.objectives import LossModule

__all__ = ["DiscriminatorLoss"]


def _bernoulli_entropy(logits: torch.Tensor) -> torch.Tensor:
    # Entropy of Bernoulli(sigmoid(x)) written on logits (authors' logit_bernoulli_entropy):
    # stable for large |x|, unlike -p log p - (1-p) log(1-p).
    return (1.0 - torch.sigmoid(logits)) * logits - F.logsigmoid(logits)


class DiscriminatorLoss(LossModule):
    """SAIL discriminator loss (authors' GAIL discriminator with entropy bonus and GP).

    The input is **one** mixed batch holding teacher rows and agent rows, told apart by
    the boolean tag ``"is_teacher"`` (shape = batch shape, no trailing 1). With
    ``\\ell`` the discriminator logits:

    - ``loss_discriminator = mean_agent BCE(ℓ, 0) + mean_teacher BCE(ℓ, 1)``: two means,
      one per class, then summed (the authors' formulation), computed from logits with
      :func:`~torch.nn.functional.binary_cross_entropy_with_logits`;
    - ``loss_entropy = -entropy_coef * mean_all H(ℓ)``, with the Bernoulli entropy
      ``H(x) = (1 - σ(x)) x - log σ(x)``: a bonus that keeps D from saturating;
    - ``loss_gradient_penalty = gp_coef * mean_i (||∂ℓ/∂x̂_i||₂ - 1)²``, where
      ``x̂_i = ε_i x_agent,i + (1 - ε_i) x_teacher,i`` is taken in the discriminator's
      *normalised feature space* (:meth:`DiscriminatorNet.features
      <torchrl_sail.DiscriminatorNet.features>`, i.e. ``[normalise(s), a]``), pairing
      the i-th teacher row with the i-th agent row for ``i < min(n_teacher, n_agent)``.

    Summing every ``loss_*`` entry gives ``L``.

    .. note:: **Departure from the authors' code.** The
        authors draw the interpolation weights once, at graph construction, as a
        fixed per-*feature* vector ``α ~ U(0, 1)^(1, obs_dim + act_dim)`` shared by
        every sample and every step, which is a bug: the penalty is then only enforced
        on one fixed affine slice between the two distributions. Here ``ε`` has one
        uniform weight per sample (shape ``[n, 1]``), resampled at every call, as in
        WGAN-GP/DAC.

    .. note:: TorchRL's :class:`~torchrl.objectives.GAILLoss` is not reused: it expects
        *probabilities* (``BCELoss`` on a sigmoid output, less stable than working on
        logits and unusable for the entropy term written on logits), splits teacher and
        agent data by key rather than by a row tag, draws independent per-element GP
        noise for observation and action, and has no entropy bonus nor normaliser
        update.

    Before the loss is computed, when ``update_obs_norm`` is ``True`` and the loss is
    in training mode (``loss.train()``, the default), the discriminator's
    :class:`~torchrl_sail.RunningObsNorm` is updated with **all** observations of the
    batch (teacher and agent), as the authors do before each discriminator minibatch.
    In eval mode (``loss.eval()``) the statistics are left untouched.

    The discriminator is held as a regular submodule (as :class:`~torchrl.objectives.RNDLoss`
    holds its predictor), not converted to functional parameters: it is shared with
    :class:`~torchrl_sail.DiscriminatorReward` and its normaliser buffers must be
    updated in place. Optimise ``loss.discriminator.parameters()``; the authors use
    Adam with lr ``1e-3`` (the TD3 learning rate).

    Args:
        discriminator (Discriminator): a :class:`~torchrl_sail.Discriminator` (or any
            :class:`~tensordict.nn.TensorDictModule` whose ``.module`` is a
            :class:`~torchrl_sail.DiscriminatorNet`). Its ``in_keys`` give the
            observation and action keys read from the batch.

    Keyword Args:
        entropy_coef (float, optional): weight of the Bernoulli entropy bonus.
            Defaults to ``0.01`` (the authors' value). A PyTorch port of SAIL
            reported that with ``0.01`` the discriminator saturated and that ``0.05``
            worked; raise it if ``d_teacher``/``d_agent`` reach 1/0 early. Schedulable:
            ``loss.entropy_coef = 0.05``.
        gp_coef (float, optional): weight of the gradient penalty. Defaults to
            ``10.0`` (the authors' value). Schedulable: ``loss.gp_coef = 5.0``.
        label_smoothing (float, optional): one-sided label smoothing (Salimans et al.): the
            teacher rows' BCE target is ``1 - label_smoothing``, the agent rows' stays 0, so
            D is not pushed to an infinite teacher logit. In ``[0, 0.5)``. Defaults to ``0.0``
            (none, the authors'). Schedulable.
        instance_noise (float, optional): standard deviation of Gaussian noise added to the
            features (normalised observation and action) of every row before the BCE and
            entropy terms, in training mode (Sønderby et al.'s instance noise): it blurs the
            two distributions so that D cannot separate them perfectly. The gradient penalty
            is taken on the clean features. Defaults to ``0.0`` (none, the authors').
            Schedulable, e.g. annealed to 0.
        update_obs_norm (bool, optional): update the discriminator's running
            observation statistics with each training batch. Defaults to ``True``.

    Returns (from ``forward``): a :class:`~tensordict.TensorDict` with empty batch size
    holding ``loss_discriminator``, ``loss_entropy``, ``loss_gradient_penalty`` and
    the detached metadata ``accuracy_teacher`` (fraction of teacher rows with
    ``σ(ℓ) > 0.5``), ``accuracy_agent`` (fraction of agent rows with ``σ(ℓ) < 0.5``),
    ``d_teacher``/``d_agent`` (mean ``σ(ℓ)``), ``entropy`` (mean ``H``),
    ``grad_penalty`` (raw GP) and ``reward_teacher``/``reward_agent`` (mean
    ``softplus(ℓ) = -log(1 - σ(ℓ))``, SAIL's and GAIL's reward), ``reward_teacher_std`` /
    ``reward_agent_std`` (their spread over the rows), ``logit_teacher`` / ``logit_agent``
    (mean logits: how far past saturation D is, and the mean of the logit reward
    ``log D - log(1 - D)``) and ``logit_teacher_std`` / ``logit_agent_std`` (their spread: how
    much the logit reward tells one row from another), all on the clean features (``entropy``
    is the loss term's, on the noisy ones). A batch without a teacher row or without an agent
    row raises a ``ValueError`` that gives both counts.

    This class is compatible with non-tensordict based modules too: the entries can
    be passed as keyword arguments named after :attr:`in_keys` and the outputs come
    back as a tuple ordered as :attr:`out_keys`.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import Discriminator, DiscriminatorLoss
        >>> disc = Discriminator(3, 1, num_cells=(32, 32))
        >>> loss_fn = DiscriminatorLoss(disc)
        >>> batch = TensorDict(
        ...     observation=torch.randn(8, 3),
        ...     action=torch.rand(8, 1) * 2 - 1,
        ...     is_teacher=torch.arange(8) < 4,
        ...     batch_size=[8],
        ... )
        >>> out = loss_fn(batch)
        >>> sorted(k for k in out.keys() if k.startswith("loss_"))
        ['loss_discriminator', 'loss_entropy', 'loss_gradient_penalty']
        >>> total = sum(v for k, v in out.items() if k.startswith("loss_"))
        >>> total.backward()
        >>> disc.net.obs_norm.count.item()  # prior 0.01 + the 8 observations
        8.01
        >>> loss_fn.entropy_coef = 0.05  # schedulable coefficient
        >>> round(loss_fn.entropy_coef.item(), 2)
        0.05

        Keyword-argument mode:

        >>> loss_d, *_ = loss_fn(
        ...     observation=torch.randn(8, 3),
        ...     action=torch.zeros(8, 1),
        ...     is_teacher=torch.arange(8) % 2 == 0,
        ... )
        >>> loss_d.shape
        torch.Size([])
    """

    @dataclass
    class _AcceptedKeys:
        """Maintains default values for all configurable tensordict keys.

        The observation, action and logit keys are those of the discriminator
        (its ``in_keys``/``out_keys``).

        Attributes:
            is_teacher (NestedKey): boolean tag, of the batch shape, that is ``True``
                on teacher rows. Defaults to ``"is_teacher"``.
        """

        is_teacher: NestedKey = "is_teacher"

    tensor_keys: _AcceptedKeys
    default_keys = _AcceptedKeys

    _schedulable_buffers = frozenset({"entropy_coef", "gp_coef", "label_smoothing", "instance_noise"})
    entropy_coef: torch.Tensor
    gp_coef: torch.Tensor
    label_smoothing: torch.Tensor
    instance_noise: torch.Tensor

    out_keys = [
        "loss_discriminator",
        "loss_entropy",
        "loss_gradient_penalty",
        "accuracy_teacher",
        "accuracy_agent",
        "d_teacher",
        "d_agent",
        "entropy",
        "grad_penalty",
        "reward_teacher",
        "reward_agent",
        "reward_teacher_std",
        "reward_agent_std",
        "logit_teacher",
        "logit_agent",
        "logit_teacher_std",
        "logit_agent_std",
    ]

    def __init__(
        self,
        discriminator: TensorDictModule,
        *,
        entropy_coef: float = 0.01,
        gp_coef: float = 10.0,
        label_smoothing: float = 0.0,
        instance_noise: float = 0.0,
        update_obs_norm: bool = True,
    ) -> None:
        if not 0.0 <= label_smoothing < 0.5:
            raise ValueError(f"label_smoothing must be in [0, 0.5), got {label_smoothing!r}.")
        if not 0.0 <= instance_noise < float("inf"):
            raise ValueError(f"instance_noise must be a finite number >= 0, got {instance_noise!r}.")
        self._in_keys = None
        super().__init__()
        self.discriminator = discriminator
        # Resolved now, so that a module without in_keys fails here, not at the first call.
        self._set_in_keys()
        self.register_coeff_buffer("entropy_coef", entropy_coef, dtype=torch.float32)
        self.register_coeff_buffer("gp_coef", gp_coef, dtype=torch.float32)
        self.register_coeff_buffer("label_smoothing", label_smoothing, dtype=torch.float32)
        self.register_coeff_buffer("instance_noise", instance_noise, dtype=torch.float32)
        self.update_obs_norm = update_obs_norm

    def _load_from_state_dict(self, state_dict, prefix, *args, **kwargs) -> None:
        # a state dict saved before label_smoothing / instance_noise existed: keep this loss's values
        for name in ("label_smoothing", "instance_noise"):
            state_dict.setdefault(prefix + name, getattr(self, name))
        super()._load_from_state_dict(state_dict, prefix, *args, **kwargs)

    @property
    def net(self):
        """The :class:`~torchrl_sail.DiscriminatorNet` being trained."""
        return self.discriminator.module

    def reset_parameters_recursive(self) -> None:
        """Re-initialises the discriminator's layers by its net's ``init`` (``DiscriminatorNet.reset_parameters``).

        The base implementation only visits networks converted to functional
        parameters; the discriminator is a plain submodule here, and resetting its
        ``nn.Linear`` layers one by one would bring back PyTorch's default init. The
        normaliser statistics are kept.
        """
        self.net.reset_parameters()

    def _set_in_keys(self) -> None:
        keys = [*self.discriminator.in_keys, self.tensor_keys.is_teacher]
        self._in_keys = list(dict.fromkeys(keys))

    def _forward_value_estimator_keys(self, **kwargs) -> None:
        # no value estimator: only the input keys depend on tensor_keys
        self._set_in_keys()

    @property
    def in_keys(self):
        if self._in_keys is None:
            self._set_in_keys()
        return self._in_keys

    @in_keys.setter
    def in_keys(self, values):
        self._in_keys = values

    def _split_rows(self, tensordict: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        obs_key, act_key = self.discriminator.in_keys
        tag = tensordict[self.tensor_keys.is_teacher]
        # A batch without one of the classes would give a NaN loss (mean over no rows).
        n_teacher = int(tag.sum())
        n_agent = tag.numel() - n_teacher
        if n_teacher == 0 or n_agent == 0:
            raise ValueError(
                f"{type(self).__name__} needs teacher and agent rows in the same batch, "
                f"got {n_teacher} rows with {self.tensor_keys.is_teacher!r}=True and "
                f"{n_agent} with False."
            )
        return tensordict[obs_key], tensordict[act_key], tag

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Computes the discriminator loss terms and metrics on a tagged mixed batch.

        Args:
            tensordict (TensorDictBase): batch with the discriminator's observation
                and action keys and the bool ``is_teacher`` tag. It is not modified.
        """
        obs, act, tag = self._split_rows(tensordict)
        net = self.net
        if self.update_obs_norm and self.training and net.obs_norm is not None:
            net.obs_norm.update(obs)

        features = net.features(obs, act)
        noisy = self.training and bool(self.instance_noise > 0)
        # a training step advances D's spectral normalisation (if any) by one power iteration
        with net.spectral_norm_iteration() if self.training else nullcontext():
            logits = net.head(features + self.instance_noise * torch.randn_like(features) if noisy else features)
        logits_teacher = logits[tag]
        logits_agent = logits[~tag]

        target_teacher = torch.ones_like(logits_teacher) - self.label_smoothing.to(logits_teacher)
        loss_bce = F.binary_cross_entropy_with_logits(
            logits_teacher, target_teacher
        ) + F.binary_cross_entropy_with_logits(logits_agent, torch.zeros_like(logits_agent))
        entropy = _bernoulli_entropy(logits).mean()
        grad_penalty = self._gradient_penalty(features[tag], features[~tag])

        with torch.no_grad():
            if noisy:  # the diagnostics describe D itself, on the clean features
                clean = net.head(features)
                logits_teacher, logits_agent = clean[tag], clean[~tag]
            p_teacher = torch.sigmoid(logits_teacher)
            p_agent = torch.sigmoid(logits_agent)
            reward_teacher = F.softplus(logits_teacher)
            reward_agent = F.softplus(logits_agent)
            metadata = {
                "accuracy_teacher": (p_teacher > 0.5).float().mean(),
                "accuracy_agent": (p_agent < 0.5).float().mean(),
                "d_teacher": p_teacher.mean(),
                "d_agent": p_agent.mean(),
                "entropy": entropy.detach(),
                "grad_penalty": grad_penalty.detach(),
                "reward_teacher": reward_teacher.mean(),
                "reward_agent": reward_agent.mean(),
                "reward_teacher_std": reward_teacher.std(correction=0),
                "reward_agent_std": reward_agent.std(correction=0),
                "logit_teacher": logits_teacher.mean(),
                "logit_agent": logits_agent.mean(),
                "logit_teacher_std": logits_teacher.std(correction=0),
                "logit_agent_std": logits_agent.std(correction=0),
            }
        return TensorDict(
            {
                "loss_discriminator": loss_bce,
                "loss_entropy": -self.entropy_coef * entropy,
                "loss_gradient_penalty": self.gp_coef * grad_penalty,
                **metadata,
            },
            batch_size=[],
        )

    def _gradient_penalty(self, features_teacher: torch.Tensor, features_agent: torch.Tensor) -> torch.Tensor:
        n = min(features_teacher.shape[0], features_agent.shape[0])
        features_teacher = features_teacher[:n].detach()
        features_agent = features_agent[:n].detach()
        eps = torch.rand(n, 1, device=features_agent.device, dtype=features_agent.dtype)
        # enable_grad: the penalty needs d logit / d x_hat even when the loss is only
        # evaluated (e.g. under torch.no_grad() for logging); the graph through the
        # gradient is only kept when the caller can backpropagate.
        create_graph = torch.is_grad_enabled()
        with torch.enable_grad():
            mixed = (eps * features_agent + (1 - eps) * features_teacher).requires_grad_(True)
            logits = self.net.head(mixed)
            (grad,) = torch.autograd.grad(logits.sum(), mixed, create_graph=create_graph)
        return (grad.norm(2, dim=-1) - 1).square().mean()
