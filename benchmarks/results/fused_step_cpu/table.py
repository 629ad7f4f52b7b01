"""Writes table.md from the four runs' summary.json: python table.py > table.md"""

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
print("| run | optim.implementation | wall s | train frames/s | update s | collect s | final eval |")
print("|---|---|---|---|---|---|---|")
for run in ("fused-1", "loss-1", "fused-2", "loss-2"):
    s = json.loads((HERE / run / "summary.json").read_text())
    wall = float((HERE / run / "wall_seconds.txt").read_text())
    seconds = s["time_seconds"]
    print(
        f"| {run} | {run.split('-')[0]} | {wall:.1f} | {s['train_frames_per_second']:.1f} | {seconds['update']:.1f} "
        f"| {seconds['collect']:.1f} | {s['final_eval_return']:.1f} |"
    )
