"""DAC's absorbing state (Kostrikov et al. 2019) as a TorchRL transform.

An episode that *terminates* (the agent fell) is not the end of time for an imitation
reward: with ``-log(1 - D) > 0`` at every step an agent learns to live forever, with
``log D - log(1 - D)`` it may learn to die early, whatever the teacher did. DAC removes the
bias by sending every terminal transition into an absorbing state ``s_a`` that loops on
itself and is bootstrapped through, so the value of ending an episode is learned from the
discriminator's reward at ``s_a`` like any other. Time-limit truncations are not
terminations and keep their next observation.
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from tensordict.utils import NestedKey
from torch import nn
from torchrl.data.tensor_specs import TensorSpec
from torchrl.envs.transforms import Transform

from torchrl_sail.envs._specs import append_unit_column

__all__ = ["AbsorbingStateTransform"]


class _ZeroAtAbsorbing(nn.Module):
    def forward(self, action: torch.Tensor, observation: torch.Tensor) -> torch.Tensor:
        return action * (1 - observation[..., -1:])


class AbsorbingStateTransform(Transform):
    """Appends DAC's absorbing-state indicator to observations and adds the absorbing transitions.

    The observation grows by one column, the indicator: ``0`` on every real state, ``1`` on the
    absorbing state ``s_a = [0, ..., 0, 1]``.

    **Environment** (inside a :class:`~torchrl.envs.TransformedEnv`): appends the indicator
    (``0``) to the observation at reset and at every step; the spec grows by one column with
    bounds ``[0, 1]`` (a ``Bounded`` spec) or stays ``Unbounded``. The policy, the critics and
    the discriminator then read observations of the same width as the stored transitions.

    **Stored transitions** (:meth:`add_absorbing_transitions`, on a flat ``[N]`` batch that
    already carries the indicator, e.g. a collected batch before ``replay.extend``): every row
    with ``("next", "terminated")`` set becomes a transition into ``s_a`` and is followed by
    one absorbing transition ``(s_a, 0, s_a)``:

    - the terminal row: ``("next", "observation") = s_a``, ``terminated = done = False``
      (its target bootstraps through ``s_a``);
    - the new row, placed right after it: ``observation = ("next", "observation") = s_a``,
      a zero action, ``("next", "reward") = 0``, ``terminated = truncated = False`` and
      ``done = True`` (the trajectory still ends once, on its last row). Other entries are
      copied from the terminal row.

    A loss that bootstraps on ``terminated`` (TD3's default, not ``set_keys(terminated="done")``)
    then learns ``Q(s_a) = r(s_a) + γ Q(s_a)``, as DAC does.

    With ``bootstrap=False`` (the SAIL authors' DAC baseline) both rows keep ``terminated =
    done = True``: the absorbing state only marks the end for the discriminator, and no value
    flows through it. With ``action_spec``, the absorbing transitions store an action drawn
    uniformly from it instead of the zero action (the SAIL authors' DAC stores
    ``env.action_space.sample()`` for the agent and the zero action for the demonstrations).

    **The policy at** ``s_a`` (:meth:`action_mask`): append ``transform.action_mask()`` to a
    deterministic actor so that ``pi(s_a) = 0``, the action of the stored absorbing
    transitions. The TD target at ``s_a`` then reads the critic where it is trained, and the
    actor gets no gradient from absorbing rows (DAC's code zeroes the target action there and
    skips those rows in the actor loss).

    **Raw transitions** (:meth:`forward`, e.g. demonstrations recorded without the
    indicator): appends the indicator to the root and ``("next", ...)`` observations, then
    adds the absorbing transitions. It is not idempotent: apply it to raw data once.

    Keyword Args:
        observation_key (NestedKey, optional): the observation. Defaults to ``"observation"``.
        action_key (NestedKey, optional): the action, zero in absorbing transitions (drawn from
            ``action_spec`` when it is given).
            Defaults to ``"action"``.
        reward_key (NestedKey, optional): the reward under ``"next"``, zeroed in absorbing
            transitions. Defaults to ``"reward"``.
        bootstrap (bool, optional): ``True``: the terminal row bootstraps through ``s_a``
            (DAC). ``False``: the terminal and absorbing rows stay terminated (the SAIL
            authors' DAC). Defaults to ``True``.
        action_spec (TensorSpec, optional): when given, absorbing transitions store a random
            action from it (``action_spec.rand()``); otherwise the zero action. Defaults to
            ``None``.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import AbsorbingStateTransform
        >>> done = torch.tensor([[False], [True], [False], [True]])
        >>> terminated = torch.tensor([[False], [True], [False], [False]])  # row 3 is a truncation
        >>> data = TensorDict({
        ...     "observation": torch.arange(4.).unsqueeze(-1), "action": torch.ones(4, 1),
        ...     "next": {"observation": torch.arange(1., 5.).unsqueeze(-1), "reward": torch.ones(4, 1),
        ...              "done": done, "terminated": terminated, "truncated": done & ~terminated},
        ... }, batch_size=[4])
        >>> out = AbsorbingStateTransform()(data)  # raw transitions: indicator, then absorbing rows
        >>> out["observation"].tolist()
        [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [2.0, 0.0], [3.0, 0.0]]
        >>> out["next", "observation"].tolist()
        [[1.0, 0.0], [0.0, 1.0], [0.0, 1.0], [3.0, 0.0], [4.0, 0.0]]
        >>> out["next", "terminated"].squeeze(-1).tolist(), out["next", "done"].squeeze(-1).tolist()
        ([False, False, False, False, False], [False, False, True, False, True])
        >>> out["action"].squeeze(-1).tolist(), out["next", "reward"].squeeze(-1).tolist()
        ([1.0, 1.0, 0.0, 1.0, 1.0], [1.0, 1.0, 0.0, 1.0, 1.0])
        >>> from torchrl.data import Bounded
        >>> authors = AbsorbingStateTransform(bootstrap=False, action_spec=Bounded(-1.0, 1.0, (1,)))
        >>> out = authors(data)  # the SAIL authors' DAC: no bootstrap through s_a, a random action there
        >>> out["next", "terminated"].squeeze(-1).tolist(), out["next", "done"].squeeze(-1).tolist()
        ([False, True, True, False, False], [False, True, True, False, True])
        >>> bool(out["action"][2].abs() <= 1)
        True
    """

    def __init__(
        self,
        *,
        observation_key: NestedKey = "observation",
        action_key: NestedKey = "action",
        reward_key: NestedKey = "reward",
        bootstrap: bool = True,
        action_spec: TensorSpec | None = None,
    ) -> None:
        super().__init__(in_keys=[observation_key], out_keys=[observation_key])
        self.action_key = action_key
        self.reward_key = reward_key
        self.bootstrap = bootstrap
        self.absorbing_action_spec = action_spec

    @property
    def observation_key(self) -> NestedKey:
        return self.in_keys[0]

    def action_mask(self) -> TensorDictModule:
        """A module that zeroes ``action_key`` where the observation is the absorbing state.

        Append it to a deterministic actor (``TensorDictSequential(actor, transform.action_mask())``):
        real states (indicator 0) keep their action, ``s_a`` gets the zero action.

        Examples:
            >>> import torch
            >>> from tensordict import TensorDict
            >>> from torchrl_sail import AbsorbingStateTransform
            >>> mask = AbsorbingStateTransform().action_mask()
            >>> td = TensorDict(action=torch.ones(2, 1), observation=torch.tensor([[3.0, 0.0], [0.0, 1.0]]),
            ...                 batch_size=[2])
            >>> mask(td)["action"].squeeze(-1).tolist()
            [1.0, 0.0]
        """
        return TensorDictModule(
            _ZeroAtAbsorbing(), in_keys=[self.action_key, self.observation_key], out_keys=[self.action_key]
        )

    def _apply_transform(self, obs: torch.Tensor) -> torch.Tensor:
        return torch.cat([obs, obs.new_zeros(*obs.shape[:-1], 1)], dim=-1)

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        return self._call(tensordict_reset)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Raw ``[N]`` transitions -> the same with the indicator and the absorbing transitions.

        Args:
            tensordict (TensorDictBase): flat transitions whose root and ``("next", ...)``
                observations lack the indicator.
        """
        tensordict = tensordict.clone(recurse=False)
        for key in (self.observation_key, ("next", self.observation_key)):
            tensordict.set(key, self._apply_transform(tensordict.get(key)))
        return self.add_absorbing_transitions(tensordict)

    def add_absorbing_transitions(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Sends terminal transitions into ``s_a`` and inserts one ``(s_a, 0, s_a)`` after each.

        Args:
            tensordict (TensorDictBase): flat ``[N]`` transitions whose observations carry the
                indicator (the output of an env with this transform).

        Reads ``("next", "terminated")``, and ``("next", "done")`` and ``("next", "truncated")``
        where a row terminated (these names, not configurable).

        Returns:
            a new ``[N + number of terminations]`` tensordict, in the input's order with each
            absorbing transition right after its terminal transition (the input is untouched),
            or the input itself when no row terminated.
        """
        terminated = tensordict.get(("next", "terminated")).reshape(-1)
        ends = terminated.nonzero().squeeze(-1)
        if not ends.numel():
            return tensordict
        obs = tensordict.get(self.observation_key)
        absorbing = obs.new_zeros(obs.shape[-1])
        absorbing[-1] = 1

        into = tensordict.clone()
        into.get(("next", self.observation_key))[ends] = absorbing
        if self.bootstrap:  # only the absorbing row ends the trajectory, and it bootstraps
            for flag in ("terminated", "done", "truncated"):
                into.get(("next", flag))[ends] = False
        loop = into[ends].clone()
        loop.set(self.observation_key, absorbing.expand_as(loop.get(self.observation_key)).clone())
        loop.set(("next", self.observation_key), absorbing.expand_as(loop.get(self.observation_key)).clone())
        action = loop.get(self.action_key)
        spec = self.absorbing_action_spec
        loop.set(
            self.action_key,
            torch.zeros_like(action)
            if spec is None
            else spec.rand(action.shape[:-1]).to(device=action.device, dtype=action.dtype),
        )
        loop.set(("next", self.reward_key), torch.zeros_like(loop.get(("next", self.reward_key))))
        loop.get(("next", "done")).fill_(True)
        if not self.bootstrap:
            loop.get(("next", "terminated")).fill_(True)
            loop.get(("next", "truncated")).fill_(False)

        # Row i of the input moves down by the number of terminations before it; the
        # absorbing row of termination j goes right after j's new position.
        n = terminated.numel()
        shift = torch.cumsum(terminated.long(), 0) - terminated.long()
        position = torch.cat([torch.arange(n, device=ends.device) + shift, ends + shift[ends] + 1])
        return torch.cat([into, loop])[torch.argsort(position)]

    def transform_observation_spec(self, observation_spec: TensorSpec) -> TensorSpec:
        key = self.observation_key
        observation_spec[key] = append_unit_column(observation_spec[key], owner="AbsorbingStateTransform", key=key)
        return observation_spec

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(observation_key={self.observation_key!r}, bootstrap={self.bootstrap}, "
            f"random_action={self.absorbing_action_spec is not None})"
        )
