"""Where a SAIL gradient step's time goes, and how it grows with the replay and batch size.

    python benchmarks/bench_update.py [--threads 1] [--iters 300] [--scale] [--critic-layer-norm]

Pieces of one training frame at the example's cadence (one TD3 step per frame: the critic
every step, the actor and the targets every second step), at the authors' sizes ([400, 300]
ReLU nets, batch 256, Hopper dims 12/3), each timed alone (median ms per call):

- sampling: TorchRL's ``TensorDictReplayBuffer.sample(256)`` [peer], ``MixedReplayBuffer``
  128 + 128 one batch per call, and per batch of a 1000-batch block (``num_batches``), each
  with and without the ``DiscriminatorReward`` recomputed at sample time, and the block
  with D run once per distinct stored row (``row_id_key``);
- the TD3 step of ``TD3Update``: the reference (``implementation="loss"``: SAILLoss's
  ``value_loss``/``actor_loss``, SoftUpdate, fp32) and the fused implementation (fp32 and
  bf16), split into critic step, actor step and target update;
- one discriminator step (256 + 256 rows, gradient penalty included).

``--critic-layer-norm`` also times the fp32 steps with a LayerNorm after each hidden layer of the
critic (``network.critic_layer_norm=true``), each against its plain peer of the same run.

``--scale`` adds the per-step cost (block sample with D reward, on every row and once per
distinct row, + fused step) and the process's resident memory for replay sizes 1e4, 1e5 and
1e6 (filled) and batch 256 and 1024.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.data import Bounded, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.modules import MLP, TanhModule, ValueOperator
from torchrl.objectives import SoftUpdate

from torchrl_sail import (
    Discriminator,
    DiscriminatorLoss,
    DiscriminatorReward,
    MixedReplayBuffer,
    SAILLoss,
    TD3Update,
    TeacherReplayBuffer,
)

OBS, ACT = 12, 3
SPEC = Bounded(-1.0, 1.0, shape=(ACT,))


def transitions(n: int, episode_len: int = 500) -> TensorDict:
    done = torch.zeros(n, 1, dtype=torch.bool)
    done[episode_len - 1 :: episode_len] = True
    done[-1] = True
    return TensorDict(
        {
            "observation": torch.randn(n, OBS),
            "action": torch.rand(n, ACT) * 2 - 1,
            "next": {
                "observation": torch.randn(n, OBS),
                "reward": torch.zeros(n, 1),
                "done": done,
                "terminated": done.clone(),
                "truncated": torch.zeros(n, 1, dtype=torch.bool),
            },
        },
        batch_size=[n],
    )


def make_update(implementation: str, precision: str, critic_layer_norm: bool = False) -> TD3Update:
    """The example's TD3 step: [400, 300] ReLU nets, fused Adam, tau 0.005; ``critic_layer_norm``:
    a LayerNorm after each hidden layer of the critic (``network.critic_layer_norm=true``)."""
    norm = (
        {"norm_class": nn.LayerNorm, "norm_kwargs": [{"normalized_shape": 400}, {"normalized_shape": 300}]}
        if critic_layer_norm
        else {}
    )
    torch.manual_seed(0)
    actor = TensorDictSequential(
        TensorDictModule(
            MLP(in_features=OBS, out_features=ACT, num_cells=[400, 300], activation_class=nn.ReLU),
            ["observation"],
            ["param"],
        ),
        TanhModule(["param"], ["action"], spec=SPEC),
    )
    critic = ValueOperator(
        MLP(in_features=OBS + ACT, out_features=1, num_cells=[400, 300], activation_class=nn.ReLU, **norm),
        in_keys=["action", "observation"],
    )
    loss = SAILLoss(actor, critic, action_spec=SPEC)
    loss.make_value_estimator(gamma=0.99)
    loss.set_keys(terminated="done")
    return TD3Update(
        loss,
        target_updater=SoftUpdate(loss, tau=0.005),
        implementation=implementation,
        precision=precision,
        critic_optimizer=torch.optim.Adam(loss.qvalue_network_params.flatten_keys().values(), lr=1e-3, fused=True),
        actor_optimizer=torch.optim.Adam(loss.actor_network_params.flatten_keys().values(), lr=1e-3, fused=True),
    )


def timed(fn, iters: int, warmup: int = 20) -> float:
    """Median ms per call of ``fn(i)``."""
    for i in range(warmup):
        fn(i)
    samples = []
    for i in range(iters):
        t0 = time.perf_counter()
        fn(i)
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples) * 1e3


def buffers(replay_size: int):
    agent = TensorDictReplayBuffer(storage=LazyTensorStorage(replay_size))
    for start in range(0, replay_size, 100_000):  # filled in chunks: no 2x peak at fill time
        agent.extend(transitions(min(100_000, replay_size - start)))
    teacher = TeacherReplayBuffer()  # top-K, K = 10
    teacher.add_demonstrations(transitions(2_000))
    return teacher, agent


def pieces(iters: int, critic_layer_norm: bool = False) -> dict:
    teacher, agent = buffers(100_000)
    disc = Discriminator(OBS, ACT)
    plain, rewarded = (
        MixedReplayBuffer(teacher, agent),
        MixedReplayBuffer(teacher, agent, transform=DiscriminatorReward(disc)),
    )
    batches = plain.sample(256, teacher_fraction=0.5, num_batches=64).unbind(0)
    rows = {
        "sample: TensorDictReplayBuffer.sample(256) [peer]": lambda i: agent.sample(256),
        "sample: Mixed 128 + 128, one batch per call": lambda i: plain.sample(256, 0.5),
        "sample: Mixed 128 + 128, per batch of a 1000-batch block": lambda i: plain.sample(256, 0.5, 1000),
        "sample + D reward, one batch per call": lambda i: rewarded.sample(256, 0.5),
        "sample + D reward, per batch of a 1000-batch block": lambda i: rewarded.sample(256, 0.5, 1000),
    }
    distinct = MixedReplayBuffer(
        teacher, agent, transform=DiscriminatorReward(disc, row_id_key="row_id"), row_id_key="row_id"
    )
    rows["sample + D reward once per distinct row, per batch of a 1000-batch block (replay 1e5)"] = lambda i: (
        distinct.sample(256, 0.5, 1000)
    )
    results = {name: timed(fn, iters if "block" not in name else max(iters // 50, 5)) for name, fn in rows.items()}
    for name in list(results):
        if "block" in name:
            results[name] /= 1000
    steps = [("loss", "fp32", False), ("fused", "fp32", False), ("fused", "bf16", False)]
    if critic_layer_norm:
        steps += [("loss", "fp32", True), ("fused", "fp32", True)]
    for implementation, precision, layer_norm in steps:
        update = make_update(implementation, precision, layer_norm)
        tag = f"TD3 step [{implementation}, {precision}{', critic LayerNorm' if layer_norm else ''}]"
        critic = timed(lambda i, update=update: update.critic_step(batches[i % 64]), iters)
        actor = timed(lambda i, update=update: update.actor_step(batches[i % 64]), iters)
        targets = timed(lambda i, update=update: update.update_targets(), iters)
        results[f"{tag} critic step"] = critic
        results[f"{tag} actor step"] = actor
        results[f"{tag} target update"] = targets
        results[f"{tag} per frame (critic + (actor + targets) / 2)"] = critic + (actor + targets) / 2
    d_loss = DiscriminatorLoss(disc)
    d_opt = torch.optim.Adam(disc.parameters(), lr=1e-3, fused=True)
    d_batches = plain.sample(512, 0.5, num_batches=64).unbind(0)

    def d_step(i):
        out = d_loss(d_batches[i % 64])
        sum(v for k, v in out.items() if k.startswith("loss_")).backward()
        d_opt.step()
        d_opt.zero_grad(set_to_none=True)

    results["discriminator step (256 + 256, GP)"] = timed(d_step, iters // 3)
    return results


def mean_ms(fn, iters: int, warmup: int = 10) -> float:
    """Mean ms per call of ``fn(i)`` (for alternating steps, whose median would pick one kind)."""
    for i in range(warmup):
        fn(i)
    t0 = time.perf_counter()
    for i in range(iters):
        fn(i)
    return (time.perf_counter() - t0) / iters * 1e3


def scale(iters: int) -> list[tuple]:
    rows = []
    update = make_update("fused", "fp32")
    disc = Discriminator(OBS, ACT)
    for replay_size in (10_000, 100_000, 1_000_000):
        teacher, agent = buffers(replay_size)
        every_row = MixedReplayBuffer(teacher, agent, transform=DiscriminatorReward(disc))
        distinct = MixedReplayBuffer(
            teacher, agent, transform=DiscriminatorReward(disc, row_id_key="row_id"), row_id_key="row_id"
        )
        for batch_size in (256, 1024):
            block_ms = [
                timed(lambda i, rb=rb, size=batch_size, alpha=alpha: rb.sample(size, alpha, 1000), 3, warmup=1) / 1000
                for rb, alpha in ((every_row, 0.5), (distinct, 0.5), (distinct, 0.0))
            ]
            block = every_row.sample(batch_size, 0.5, 100).unbind(0)
            step_ms = mean_ms(lambda i, block=block: update(block[i % 100], update_actor=i % 2 == 0), iters)
            rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            rows.append((replay_size, batch_size, *block_ms, step_ms, rss))
        del teacher, agent, every_row, distinct
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--iters", type=int, default=300)
    parser.add_argument("--scale", action="store_true", help="also time replay 1e5/1e6 x batch 256/1024")
    parser.add_argument(
        "--critic-layer-norm", action="store_true", help="also time the fp32 TD3 steps with a LayerNorm critic"
    )
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"torch {torch.__version__}, threads={args.threads}, iters={args.iters}")
    results = pieces(args.iters, args.critic_layer_norm)
    for name, ms in results.items():
        print(f"{name:70s} {ms:8.3f} ms")
    ref = results["TD3 step [loss, fp32] per frame (critic + (actor + targets) / 2)"]
    for precision in ("fp32", "bf16"):
        fused = results[f"TD3 step [fused, {precision}] per frame (critic + (actor + targets) / 2)"]
        print(f"TD3 step per frame, reference fp32 / fused {precision}: {ref / fused:.2f}x")
    if args.critic_layer_norm:
        for implementation in ("loss", "fused"):
            plain = results[f"TD3 step [{implementation}, fp32] per frame (critic + (actor + targets) / 2)"]
            normed = results[
                f"TD3 step [{implementation}, fp32, critic LayerNorm] per frame (critic + (actor + targets) / 2)"
            ]
            print(f"TD3 step per frame [{implementation}, fp32], critic LayerNorm / without: {normed / plain:.2f}x")
    if args.scale:
        print(
            "block sample + D reward, ms per step: every row (alpha 0.5) | once per distinct row (alpha 0.5) "
            "| once per distinct row (alpha 0, all rows from the replay)"
        )
        print(
            "| replay (filled) | batch | every row | distinct, alpha 0.5 | distinct, alpha 0 "
            "| fused step, ms (mean) | peak RSS MB |"
        )
        print("|---|---|---|---|---|---|---|")
        for replay_size, batch_size, every, half, zero, step_ms, rss in scale(args.iters):
            print(
                f"| {replay_size:.0e} | {batch_size} | {every:.3f} | {half:.3f} | {zero:.3f} | {step_ms:.2f} "
                f"| {rss:.0f} |"
            )


if __name__ == "__main__":
    main()
