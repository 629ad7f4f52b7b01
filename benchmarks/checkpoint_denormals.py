"""How many denormal floats a run's checkpoint holds: the networks and their Adam moments, tensor by tensor.

    python benchmarks/checkpoint_denormals.py RUN_DIR

For the off-policy TD3 methods of ``examples/sail_td3.py``. Rebuilds the run's networks, losses
and optimizers from its ``config.yaml`` (over the schema's defaults, as ``examples/evaluate.py``
does), loads its last checkpoint on the CPU and prints one Markdown row per float32 tensor with
any denormal value (nonzero and below float32's smallest normal, 1.18e-38): the actor's and
the critics' parameters (the loss's copies, which TD3 trains) and each optimizer's per-parameter
state (``exp_avg``, ``exp_avg_sq``), then one total row per group. x86 CPUs compute with
denormals many times slower than with normal floats, unless they are flushed to zero
(``flush_denormal=true``, the default); a checkpoint saved with that on holds none.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch
from torchrl.checkpoint import Checkpoint

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "examples"))

from evaluate import load_run  # noqa: E402
from utils import make_agent, make_discriminator, make_env, make_losses, make_optimizers  # noqa: E402

from torchrl_sail.harness import checkpoint_dir  # noqa: E402

HEADER = "| group | tensor | shape | denormal | share |\n|---|---|---|---|---|"
GROUPS = ("loss", "optim_actor", "optim_critic")


def denormal_count(tensor: torch.Tensor) -> int:
    """Nonzero float32 values below the smallest normal, read from their bits: with denormals
    flushed in this process the CPU would read them as 0."""
    bits = tensor.contiguous().view(torch.int32)
    return int((((bits & 0x7F800000) == 0) & ((bits & 0x007FFFFF) != 0)).sum())


def load(run_dir: Path) -> dict[str, dict[str, torch.Tensor]]:
    """``{group: {name: tensor}}`` of the run's checkpoint: the loss's parameters and each TD3 optimizer's state."""
    cfg, _ = load_run(run_dir)
    if cfg.algo.learner != "td3":
        raise ValueError(f"{run_dir}: algo={cfg.algo.name} is not a TD3 method (algo.learner={cfg.algo.learner})")
    cfg.device = "cpu"
    env = make_env(cfg, cfg.seed)
    actor, critic, _ = make_agent(cfg, env)
    discriminator = make_discriminator(cfg, env)
    loss, *_ = make_losses(cfg, actor, critic, discriminator, env.action_spec)
    optimizers = make_optimizers(cfg, loss, discriminator)
    Checkpoint(loss=loss, optim_actor=optimizers["actor"], optim_critic=optimizers["critic"]).load(
        checkpoint_dir(run_dir), components=list(GROUPS), map_location="cpu"
    )
    names = {id(p): name for name, p in loss.named_parameters()}
    tensors = {"loss": {name: p.detach() for name, p in loss.named_parameters()}}
    for group in GROUPS[1:]:
        optimizer = optimizers[group.removeprefix("optim_")]
        tensors[group] = {
            f"{names[id(p)]}.{key}": value
            for p, state in optimizer.state.items()
            for key, value in state.items()
            if key != "step"
        }
    return tensors


def table(tensors: dict[str, dict[str, torch.Tensor]]) -> str:
    lines = [HEADER]
    for group, named in tensors.items():
        total = sum(t.numel() for t in named.values() if t.dtype == torch.float32)
        found = 0
        for name, t in named.items():
            if t.dtype != torch.float32 or not (count := denormal_count(t)):
                continue
            found += count
            lines.append(f"| {group} | {name} | {tuple(t.shape)} | {count} | {count / t.numel():.1%} |")
        lines.append(f"| {group} | **all** | | **{found}** | {found / max(total, 1):.1%} |")
    return "\n".join(lines)


def main(argv=None) -> dict[str, dict[str, torch.Tensor]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    args = parser.parse_args(argv)
    tensors = load(args.run_dir)
    print(table(tensors))
    return tensors


if __name__ == "__main__":
    main()
