"""TD3Update's fused step against TorchRL's loss-based step, eager and under ``torch.compile``.

    python benchmarks/bench_compile.py [--threads 1] [--steps 2000] [--repeats 3]

The loss-based step is TorchRL's sota ``td3.py`` ``update``: ``loss.value_loss``, backward, the
critic's Adam step, then every second step ``loss.actor_loss``, backward, the actor's Adam step
and ``SoftUpdate.step()``. It runs eager and compiled the way that script compiles it
(``torch.compile(update)``, inductor's default mode on a CPU; one graph per ``update_actor``
value). Its peer is ``TD3Update(implementation="fused")``, fp32. All three build the example's
networks ([400, 300] ReLU, Hopper dims 12/3, batch 256, tau 0.005, fused Adam) from one seed,
run on the same batches in the same order, and are timed alternately, ``--repeats`` rounds of
``--steps`` steps each (compile time excluded: each variant runs 50 steps first). Prints mean ms
per step (critic every step, actor and targets every second), the ratios, and how far one step
from the same weights on the same batch, with the same policy-smoothing noise, lands the compiled
and the fused steps from the eager one: the largest weight difference, and the weights that differ
by more than 1e-6 with the largest eager gradient among them. Adam's first step moves a weight by
about ``lr * g / (|g| + eps)``, which rounding of a gradient near ``eps`` (1e-8) changes most.
The compiled step draws that noise from eager's random stream there (inductor's
``fallback_random``; its own generator would draw other noise, and the weights would land up to
``2 * lr`` apart). Denormals are flushed, as the training scripts do (``flush_denormal=true``).
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch
import torch._inductor.config as inductor_config
from bench_update import make_update, transitions
from tensordict import TensorDict

from torchrl_sail.harness import cpu_model

KINDS = {"fused": "fused", "loss": "loss", "compiled": "loss"}  # each variant's TD3Update implementation


def sota_update(td3):
    """TorchRL's sota ``td3.py`` update function on a ``TD3Update``'s loss, optimizers and target updater."""
    loss, critic_opt, actor_opt, targets = td3.loss, td3.critic_optimizer, td3.actor_optimizer, td3.target_updater

    def update(batch: TensorDict, update_actor: bool):
        q_loss, _ = loss.value_loss(batch)
        q_loss.backward()
        critic_opt.step()
        critic_opt.zero_grad(set_to_none=True)
        if update_actor:
            actor_loss, _ = loss.actor_loss(batch)
            actor_loss.backward()
            actor_opt.step()
            actor_opt.zero_grad(set_to_none=True)
            targets.step()
        return q_loss.detach()

    return update


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-flush-denormal", action="store_true", help="keep denormals (the scripts flush them)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    flush = torch.set_flush_denormal(not args.no_flush_denormal)
    print(
        f"torch {torch.__version__}, threads={args.threads}, steps={args.steps}, repeats={args.repeats}, "
        f"flush_denormal={flush}, cpu={cpu_model()}"
    )

    rows = transitions(64 * 256)
    rows["next", "reward"] = torch.randn(len(rows), 1)
    batches = rows.reshape(64, 256).unbind(0)
    fused_td3, eager_td3, compiled_td3 = (make_update(kind, "fp32") for kind in ("fused", "loss", "loss"))
    variants = {
        "fused (TD3Update)": fused_td3,
        "loss, eager": sota_update(eager_td3),
        "loss, torch.compile": torch.compile(sota_update(compiled_td3)),
    }

    def run(update, steps: int, offset: int = 0) -> float:
        t0 = time.perf_counter()
        for i in range(offset, offset + steps):
            update(batches[i % 64], update_actor=i % 2 == 1)
        return (time.perf_counter() - t0) / steps * 1e3

    t0 = time.perf_counter()
    for update in variants.values():
        run(update, 50)
    print(f"warm-up (compile included): {time.perf_counter() - t0:.1f} s")
    times = {name: [] for name in variants}
    for r in range(args.repeats):
        for name, update in variants.items():
            times[name].append(run(update, args.steps, offset=50 + r * args.steps))
    means = {name: statistics.mean(values) for name, values in times.items()}
    for name, values in times.items():
        print(f"{name:24s} {means[name]:7.3f} ms/step  (rounds: {', '.join(f'{v:.3f}' for v in values)})")
    fused = means["fused (TD3Update)"]
    for name in ("loss, eager", "loss, torch.compile"):
        print(f"{name} / fused: {means[name] / fused:.2f}x")
    # one critic + actor step from the same weights on the same batch with the same noise
    one = {kind: make_update(implementation, "fp32") for kind, implementation in KINDS.items()}
    grads = eager_gradients(one["loss"])
    one_step = {
        "fused": one["fused"],
        "loss": sota_update(one["loss"]),
        "compiled": torch.compile(sota_update(one["compiled"])),
    }
    torch._dynamo.reset()  # compile anew: the timed graphs draw from inductor's own generator
    with inductor_config.patch(fallback_random=True):  # compiled here: eager's random stream
        for update in one_step.values():
            torch.manual_seed(1)  # the policy-smoothing noise
            update(batches[0], update_actor=True)
    for kind in ("compiled", "fused"):
        gap, apart, gradient = 0.0, 0, 0.0
        for params in ("actor_network_params", "qvalue_network_params"):
            for a, b in zip(
                getattr(one[kind].loss, params).flatten_keys().values(),
                getattr(one["loss"].loss, params).flatten_keys().values(),
                strict=True,
            ):
                difference = (a - b).abs()
                gap, far = max(gap, difference.max().item()), difference > 1e-6
                apart += int(far.sum())
                if far.any():
                    gradient = max(gradient, grads[b.data_ptr()][far].abs().max().item())
        far = f"{apart} weights, their eager gradients at most {gradient:.1e}" if apart else "none"
        print(
            f"one step from the same weights, largest weight difference {kind} vs loss eager: {gap:.2e} "
            f"(by more than 1e-6: {far})"
        )


def eager_gradients(td3) -> dict[int, torch.Tensor]:
    """The gradient each parameter of ``td3``'s optimizers steps with, by the parameter's ``data_ptr()``
    (filled at its next step)."""
    grads = {}
    for optimizer in (td3.critic_optimizer, td3.actor_optimizer):
        params = [p for group in optimizer.param_groups for p in group["params"]]

        def record(*_, params=params):
            grads.update({p.data_ptr(): p.grad.clone() for p in params if p.grad is not None})

        optimizer.register_step_pre_hook(record)
    return grads


if __name__ == "__main__":
    main()
