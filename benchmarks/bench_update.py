"""Cost of one SAIL gradient step against its TorchRL peer, measured in the same process.

    python benchmarks/bench_update.py [--threads 1] [--iters 300]

Peer = plain TorchRL TD3: ``TensorDictReplayBuffer.sample(256)`` + ``TD3Loss`` critic and
actor steps. SAIL = ``MixedReplayBuffer.sample(256, teacher_fraction=0.5)`` (128 teacher +
128 agent rows) with the ``DiscriminatorReward`` recomputed at sample time + ``SAILLoss``
critic and actor steps.
Both use the authors' sizes ([400, 300] ReLU nets, batch 256, Hopper dims 12/3), and
both take an actor step every update (an upper bound on TD3's policy_delay=2 cost).
Also timed: one discriminator step (256 + 256 rows, gradient penalty included) and the
sampling pieces alone. Reports the median ms per call and SAIL / peer ratios.
"""
from __future__ import annotations

import argparse
import statistics
import time

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.data import Bounded, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.modules import MLP, TanhModule, ValueOperator
from torchrl.objectives import SoftUpdate, TD3Loss

from torchrl_sail import (
    Discriminator,
    DiscriminatorLoss,
    DiscriminatorReward,
    MixedReplayBuffer,
    SAILLoss,
    TeacherReplayBuffer,
)

OBS, ACT, BATCH = 12, 3, 256


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


def agent_nets(spec):
    actor = TensorDictSequential(
        TensorDictModule(MLP(in_features=OBS, out_features=ACT, num_cells=[400, 300],
                             activation_class=nn.ReLU), ["observation"], ["param"]),
        TanhModule(["param"], ["action"], spec=spec),
    )
    critic = ValueOperator(MLP(in_features=OBS + ACT, out_features=1, num_cells=[400, 300],
                               activation_class=nn.ReLU), in_keys=["action", "observation"])
    return actor, critic


def make_step(loss, sample):
    updater = SoftUpdate(loss, tau=0.005)
    critic_opt = torch.optim.Adam(loss.qvalue_network_params.flatten_keys().values(), lr=1e-3)
    actor_opt = torch.optim.Adam(loss.actor_network_params.flatten_keys().values(), lr=1e-3)

    def step():
        batch = sample()
        loss_q, _ = loss.value_loss(batch)
        critic_opt.zero_grad()
        loss_q.backward()
        critic_opt.step()
        loss_a, _ = loss.actor_loss(batch)
        actor_opt.zero_grad()
        loss_a.backward()
        actor_opt.step()
        updater.step()

    return step


def timed(fn, iters: int, warmup: int = 20) -> float:
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(iters):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples) * 1e3


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--iters", type=int, default=300)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    spec = Bounded(-1.0, 1.0, shape=(ACT,))

    agent = TensorDictReplayBuffer(storage=LazyTensorStorage(100_000))
    agent.extend(transitions(100_000))
    teacher = TeacherReplayBuffer()  # top-K, K = 10
    teacher.add_demonstrations(transitions(2_000))
    disc = Discriminator(OBS, ACT)
    mixer = MixedReplayBuffer(teacher, agent, transform=DiscriminatorReward(disc))
    d_mixer = MixedReplayBuffer(teacher, agent)

    td3 = TD3Loss(*agent_nets(spec), action_spec=spec, loss_function="l2")
    td3.make_value_estimator(gamma=0.99)
    sail = SAILLoss(*agent_nets(spec), action_spec=spec, alpha=0.5)
    sail.make_value_estimator(gamma=0.99)
    d_loss = DiscriminatorLoss(disc)
    d_opt = torch.optim.Adam(disc.parameters(), lr=1e-3)

    def d_step():
        out = d_loss(d_mixer.sample(2 * BATCH, teacher_fraction=0.5))
        total = sum(v for k, v in out.items() if k.startswith("loss_"))
        d_opt.zero_grad()
        total.backward()
        d_opt.step()

    rows = [
        ("sample: TensorDictReplayBuffer.sample(256)  [peer]", lambda: agent.sample(BATCH)),
        ("sample: MixedReplayBuffer, 128 + 128", lambda: d_mixer.sample(BATCH, teacher_fraction=0.5)),
        ("sample: Mixed + DiscriminatorReward", lambda: mixer.sample(BATCH, teacher_fraction=0.5)),
        ("update: TD3Loss on plain sample            [peer]", make_step(td3, lambda: agent.sample(BATCH))),
        ("update: SAILLoss on mixed + D-reward sample", make_step(sail, lambda: mixer.sample(BATCH, teacher_fraction=0.5))),
        ("update: discriminator step (256 + 256, GP)", d_step),
    ]
    results = {}
    print(f"torch {torch.__version__}, threads={args.threads}, iters={args.iters}, batch={BATCH}")
    for name, fn in rows:
        results[name] = timed(fn, args.iters)
        print(f"{name:55s} {results[name]:8.3f} ms")
    names = list(results)
    print(f"ratio sample (mixed + D reward) / peer sample : {results[names[2]] / results[names[0]]:.2f}x")
    print(f"ratio SAIL update / TD3 update                : {results[names[4]] / results[names[3]]:.2f}x")
    # Per 1000 env frames at the authors' cadence: 1000 SAIL updates + 20 D steps.
    per_k = (1000 * results[names[4]] + 20 * results[names[5]]) / 1e3
    print(f"learner time per 1000 env frames (1000 SAIL + 20 D steps): {per_k:.1f} s")


if __name__ == "__main__":
    main()
