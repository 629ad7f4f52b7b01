"""Exports demonstrations as a local Minari dataset (the gymnasium ecosystem's offline-data format).

    python examples/export_minari.py --env Hopper-v4 --dataset-id sail/Hopper-v4/teacher-v0
    python examples/export_minari.py --env Hopper-v4 --dataset-id sail/Hopper-v4/paper-v0 \\
        --source <teachers>/expert_data_no_img_Hopper_scores_1500_episodes_10.npz

The source is anything ``load_demonstrations`` reads (a ``.npz`` file, a demonstrations folder,
``minari:<id>``); by default the teacher shipped for ``--env``. The dataset goes under ``--root``,
by default ``MINARI_DATASETS_PATH`` (else ``~/.minari/datasets``); SAIL trains on it with
``teacher.path=minari:<dataset id>``. Needs ``pip install -e '.[minari]'``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from torchrl_sail import export_minari_dataset, load_demonstrations, load_minari_demonstrations

TEACHERS_DIR = Path(__file__).resolve().parent / "teachers"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add = parser.add_argument
    add("--dataset-id", required=True, help="(namespace/)name-v<version>, e.g. sail/Hopper-v4/teacher-v0")
    add("--source", help="a .npz file, a demonstrations folder or minari:<id> (default: --env's teacher)")
    add("--env", help="gymnasium id stored as the dataset's env spec (default: the source's env_id)")
    add("--root", help="datasets folder (default: MINARI_DATASETS_PATH, else ~/.minari/datasets)")
    add("--max-episode-steps", type=int, default=1000, help="time limit T of the recording")
    add("--author", help="Minari metadata: author")
    add("--algorithm-name", help="Minari metadata: how the demonstrations were made")
    add("--description", help="Minari metadata: description (default: names the source)")
    add("--overwrite", action="store_true", help="replace an existing dataset of that id")
    args = parser.parse_args(argv)
    if args.source is None and args.env is None:
        parser.error("give --source, or --env to export the teacher shipped for that env")
    source = args.source if args.source is not None else TEACHERS_DIR / args.env

    demos = load_demonstrations(source, max_episode_steps=args.max_episode_steps)
    path = export_minari_dataset(
        demos,
        args.dataset_id,
        env=args.env,
        root=args.root,
        algorithm_name=args.algorithm_name,
        author=args.author,
        description=args.description,
        overwrite=args.overwrite,
    )
    # read back what was written
    _, meta = load_minari_demonstrations(path, max_episode_steps=args.max_episode_steps)
    returns = meta["episode_returns"]
    shown = ", ".join(f"{r:.1f}" for r in returns[:10]) + (", ..." if len(returns) > 10 else "")
    print(f"wrote {path}")
    n = meta["n_episodes"]
    print(
        f"  {n} episode{'s' * (n != 1)}, {meta['n_transitions']} transitions, env {meta.get('env_id')}, "
        f"time feature {meta['time_feature']}"
    )
    print(f"  returns [{shown}] (mean {sum(returns) / len(returns):.1f})")
    env = f"env={meta['env_id']} " if meta.get("env_id") else ""
    print(f"train on it: python examples/sail_td3.py {env}teacher.path=minari:{args.dataset_id}")


if __name__ == "__main__":
    main()
