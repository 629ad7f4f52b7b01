"""``benchmarks/checkpoint_actor.py``: the TD3 actor's saturation and its critic's slopes at a checkpoint."""

from __future__ import annotations

import math

import pytest
import torch
from benchmark_scripts import load_benchmark
from example_runner import run
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential
from test_example import HOPPER, TINY
from torchrl.data import Bounded
from torchrl.modules import MLP, TanhModule, ValueOperator

from torchrl_sail import SAILLoss

checkpoint_actor = load_benchmark("checkpoint_actor")
OBS, ACT = 3, 2


def linear_loss(c: float, w: list[float]) -> SAILLoss:
    """An actor with the constant pre-tanh output c on [-1, 1]^2, a critic Q(s, a) = w . a + 10 sum(w)."""
    spec = Bounded(-torch.ones(ACT), torch.ones(ACT), (ACT,))
    actor = TensorDictSequential(
        TensorDictModule(MLP(in_features=OBS, out_features=ACT, num_cells=[4]), ["observation"], ["param"]),
        TanhModule(["param"], ["action"], spec=spec),
    )
    critic = ValueOperator(
        MLP(in_features=ACT + OBS, out_features=1, num_cells=[ACT], activation_class=torch.nn.ReLU),
        in_keys=["action", "observation"],
    )
    a_mlp = actor.module[0].module
    with torch.no_grad():
        for p in a_mlp.parameters():
            p.zero_()
        a_mlp[-1].bias.fill_(c)
    loss = SAILLoss(actor, critic, action_spec=spec)
    # TD3Loss draws each critic copy's weights anew: set the first one's, which the tool reads
    q = loss.qvalue_network_params[0]
    with torch.no_grad():
        for p in q.values(True, True):
            p.zero_()
        q["module", "0", "weight"][:, :ACT] = torch.eye(ACT)  # hidden j = relu(a_j + 10) = a_j + 10
        q["module", "0", "bias"].fill_(10.0)
        q["module", "2", "weight"][0] = torch.tensor(w)
    return loss


def test_summarize_against_hand_computed_values():
    c, w = 3.0, [0.5, -2.0]
    loss = linear_loss(c, w)
    rows = TensorDict(observation=torch.randn(4, OBS), action=torch.tensor([[1.0, 0.0]] * 3 + [[0.995, -1.0]]))
    rows.batch_size = [4]
    stats = checkpoint_actor.summarize(loss, rows)
    t = math.tanh(c)
    assert stats["count"] == 4
    assert stats["stored_saturated"] == pytest.approx(5 / 8)  # 1.0 x3, 0.995, -1.0
    assert stats["pi_saturated"] == 1.0 and stats["preactivation"] == pytest.approx(c)  # tanh(3) = 0.995
    assert stats["dq_da"] == pytest.approx((0.5 + 2.0) / 2)
    assert stats["dq_dx"] == pytest.approx((0.5 + 2.0) / 2 * (1 - t**2), rel=1e-5)
    assert stats["q_pi"] == pytest.approx(0.5 * (t + 10) - 2.0 * (t + 10), rel=1e-5)
    assert stats["q_centre"] == pytest.approx(10 * (0.5 - 2.0), rel=1e-5)
    assert checkpoint_actor.summarize(loss, rows[:0]) == {"count": 0}
    lines = checkpoint_actor.table({"agent": stats, "none": {"count": 0}}).splitlines()
    assert lines[2].startswith("| agent | 4 | 0.625 | 1.000 | 3.00 | 1.25 | 0.0123 |")
    assert lines[3] == "| none | 0 | - | - | - | - | - | - | - |"


def test_recent_must_be_positive():
    with pytest.raises(SystemExit):
        checkpoint_actor.parse_args(["run", "--recent", "0"])


@pytest.mark.slow  # runs the example
def test_groups_of_a_sail_checkpoint(tmp_path, teacher_dir, capsys):
    run_dir = tmp_path / "sail"
    run(
        run_dir,
        f"teacher.path={teacher_dir / HOPPER}",
        "env=Hopper-v4",
        "collector.total_frames=2000",
        "logger.backends=[csv]",
        *TINY,
    )
    stats = checkpoint_actor.main([str(run_dir), "--recent", "500"])
    assert "checkpoint at 2000 frames" in capsys.readouterr().out
    assert list(stats) == ["teacher buffer", "agent, all", "agent, latest 500"]
    assert stats["teacher buffer"]["count"] == 425 and stats["agent, all"]["count"] == 2000
    for group in stats.values():
        assert 0 <= group["pi_saturated"] <= 1 and group["preactivation"] > 0 and group["dq_dx"] <= group["dq_da"]
    # the actor's own saturation agrees with the logged one's definition on the same rows
    cfg, _, loss, _, agent = checkpoint_actor.load(run_dir)
    x = loss.actor_network.module[0](agent[-500:].select("observation").copy())["param"]
    assert stats["agent, latest 500"]["pi_saturated"] == pytest.approx(
        (x.abs() >= math.atanh(0.99)).float().mean().item(), abs=1e-6
    )
    # a SAC run (the same checkpoint, its config saying so) is refused by name
    config = run_dir / "config.yaml"
    config.write_text(config.read_text().replace("learner: td3", "learner: sac"))
    with pytest.raises(ValueError, match="this tool reads TD3 runs"):
        checkpoint_actor.main([str(run_dir)])
