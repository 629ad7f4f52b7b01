"""The transition keys every SAIL data container agrees on (see the README's data conventions)."""

from __future__ import annotations

from tensordict.utils import NestedKey

# What a stored transition needs for the TD3 target, the discriminator and the promotion
# test; anything else a collector adds (traj ids, step counts, returns) is optional.
TRANSITION_KEYS: tuple[NestedKey, ...] = (
    "observation",
    "action",
    ("next", "observation"),
    ("next", "reward"),
    ("next", "done"),
    ("next", "terminated"),
    ("next", "truncated"),
)
