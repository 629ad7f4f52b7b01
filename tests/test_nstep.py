"""Tests for NStepTransform and nstep_view (envs/nstep.py): DDPGfD's n-step view beside the 1-step transition.

One hand-computed stream, n = 3, gamma = 0.5, rewards r_t = t + 1, observations s_t = t and
("next", "observation") = t + 0.5: episode A is steps 0..3 (terminated at 3), B is 4..6
(truncated at 6), C starts at 7 and goes on. It arrives in collector batches [0..4], [5..9],
[10, 11], so windows cross both batch boundaries and both episode ends.
"""

from __future__ import annotations

import argparse

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs.transforms import MultiStepTransform

from torchrl_sail import NStepTransform, nstep_view

N, GAMMA = 3, 0.5
# t: (n-step reward, bootstrap observation s_{t+k}'s entry, k, terminated, truncated), by hand
EXPECTED = {
    0: (1 + 0.5 * 2 + 0.25 * 3, 2.5, 3, False, False),
    1: (2 + 0.5 * 3 + 0.25 * 4, 3.5, 3, True, False),  # the window ends at the termination
    2: (3 + 0.5 * 4, 3.5, 2, True, False),  # cut at the episode end, crosses batches 1 | 2
    3: (4, 3.5, 1, True, False),
    4: (5 + 0.5 * 6 + 0.25 * 7, 6.5, 3, False, True),  # crosses batches 1 | 2, ends at a truncation
    5: (6 + 0.5 * 7, 6.5, 2, False, True),
    6: (7, 6.5, 1, False, True),
    7: (8 + 0.5 * 9 + 0.25 * 10, 9.5, 3, False, False),  # never into episode B's rewards
    8: (9 + 0.5 * 10 + 0.25 * 11, 10.5, 3, False, False),  # crosses batches 2 | 3
}


def stream(ts, *, done_at=(3, 6), terminated_at=(3,), offset=0.0):
    t = torch.tensor(ts, dtype=torch.float32).unsqueeze(-1)
    done, terminated = torch.isin(t, torch.tensor(done_at)), torch.isin(t, torch.tensor(terminated_at))
    return TensorDict(
        {
            "observation": t + offset,
            "action": torch.zeros(len(ts), 2),
            ("next", "observation"): t + offset + 0.5,
            ("next", "reward"): t + offset + 1,
            ("next", "done"): done,
            ("next", "terminated"): terminated,
            ("next", "truncated"): done & ~terminated,
        },
        [len(ts)],
    )


def check(out, ts):
    assert out["observation"].squeeze(-1).tolist() == ts
    assert out["next", "reward"].squeeze(-1).tolist() == [t + 1 for t in ts]  # the 1-step transition is kept
    assert out["next", "observation"].squeeze(-1).tolist() == [t + 0.5 for t in ts]
    reward, obs, steps, terminated, truncated = zip(*(EXPECTED[t] for t in ts), strict=True)
    view = out["next_n"]
    torch.testing.assert_close(view["reward"].squeeze(-1), torch.tensor(reward), rtol=0, atol=1e-6)
    assert view["observation"].squeeze(-1).tolist() == list(obs)
    assert view["steps_to_next_obs"].squeeze(-1).tolist() == list(steps)
    assert view["terminated"].squeeze(-1).tolist() == list(terminated)
    assert view["truncated"].squeeze(-1).tolist() == list(truncated)
    assert view["done"].squeeze(-1).tolist() == [a or b for a, b in zip(terminated, truncated, strict=True)]
    assert view["steps_to_next_obs"].shape == view["reward"].shape  # what the estimators' view_as needs


class TestNStepTransform:
    def test_stream_across_batches_and_episode_ends(self):
        nstep = NStepTransform(N, GAMMA)
        first = stream(range(0, 5))
        check(nstep.inv(first), [0, 1])
        first.apply_(torch.zeros_like)  # a collector reusing its batch: the held-back steps were copied
        check(nstep.inv(stream(range(5, 10))), [2, 3, 4, 5, 6])
        check(nstep.inv(stream(range(10, 12))), [7, 8])

    def test_batches_shorter_than_the_window(self):
        # 2-step batches: nothing is ready after the first; every step comes out once, in order
        nstep, seen = NStepTransform(N, GAMMA), []
        for start in range(0, 12, 2):
            out = nstep.inv(stream(range(start, start + 2)))
            ts = out["observation"].squeeze(-1).tolist()
            assert ts == list(range(max(start - 3, 0), start - 1))  # the steps with n steps of lookahead
            if ts:
                check(out, ts)
            seen += ts
        assert seen == list(range(9))

    def test_streams_are_independent(self):
        # [B, T] collector batches: the window runs along time in each stream
        nstep = NStepTransform(N, GAMMA)
        batches = [
            torch.stack([stream(ts), stream(ts, done_at=(), terminated_at=(), offset=100.0)])
            for ts in (range(0, 5), range(5, 10))
        ]
        nstep.inv(batches[0])
        out = nstep.inv(batches[1])
        check(out[0], [2, 3, 4, 5, 6])
        r = [t + 101.0 for t in range(2, 9)]  # the second stream never ends: full windows
        torch.testing.assert_close(
            out[1]["next_n", "reward"].squeeze(-1),
            torch.tensor([r[i] + 0.5 * r[i + 1] + 0.25 * r[i + 2] for i in range(5)]),
        )
        assert out[1]["next_n", "observation"].squeeze(-1).tolist() == [104.5, 105.5, 106.5, 107.5, 108.5]

    def test_same_lookahead_as_torchrl_multistep(self):
        # TorchRL's transform computes the same sums, bootstrap observations and step counts
        # (into "next"); it keeps step t's done flags, the n-step view has the window end's.
        ours, theirs = NStepTransform(N, GAMMA), MultiStepTransform(N, GAMMA)
        for ts in (range(0, 5), range(5, 10)):
            out, ref = ours.inv(stream(ts)), theirs.inv(stream(ts))
            torch.testing.assert_close(out["next_n", "reward"], ref["next", "reward"])
            torch.testing.assert_close(out["next_n", "observation"], ref["next", "observation"])
            assert out["next_n", "steps_to_next_obs"].squeeze(-1).tolist() == ref["steps_to_next_obs"].tolist()
        # t = 2 (the first row out of the second batch): its window ends at the termination at t = 3
        assert not ref["next", "terminated"][0] and out["next_n", "terminated"][0]

    def test_whole_trajectories(self):
        # demonstrations: whole episodes at once, nothing held back
        nstep = NStepTransform(N, GAMMA)
        check(nstep.apply_to_trajectories(stream(range(0, 7))), list(range(7)))
        with pytest.raises(ValueError, match="needs whole episodes"):
            nstep.apply_to_trajectories(stream(range(0, 9)))

    def test_view_is_what_a_td0_estimator_reads(self):
        batch = NStepTransform(N, GAMMA).apply_to_trajectories(stream(range(0, 7)))
        view = nstep_view(batch)
        assert view["next", "reward"] is batch["next_n", "reward"] and view["observation"] is batch["observation"]
        assert "next_n" not in view.keys() and ("next", "steps_to_next_obs") not in view.keys(True)
        assert view["steps_to_next_obs"].squeeze(-1).tolist() == [3, 3, 2, 1, 3, 2, 1]
        assert nstep_view(batch, steps_key=("a", "b"))["a", "b"] is batch["next_n", "steps_to_next_obs"]

    def test_refuses(self):
        with pytest.raises(ValueError, match="overwrite the 1-step transition"):
            NStepTransform(N, GAMMA, out_key="next")
        with pytest.raises(ValueError, match="n_steps must be a strictly positive integer"):
            NStepTransform(0, GAMMA)
        with pytest.raises(ValueError, match="gamma must be in"):
            NStepTransform(N, 0.0)
        with pytest.raises(ValueError, match="only an inverse transform"):
            NStepTransform(N, GAMMA)._call(stream([0]))


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)
