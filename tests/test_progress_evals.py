"""``benchmarks/progress_evals.py``: an evaluation curve rebuilt from a run's progress log."""

from __future__ import annotations

import json

import pytest
import yaml
from benchmark_scripts import load_benchmark

from torchrl_sail.harness import read_scalar

progress_evals = load_benchmark("progress_evals")

# tqdm's lines as the example writes them: the postfix is refreshed after the line for the same frame count
LOG = (
    "  0%|          | 500/30000 [00:00<02:30, 659.62frames/s, C=148, alpha=0.50, eval=-, fps=660, ret=14]\r"
    " 33%|###       | 10000/30000 [00:10<00:20, 700.00frames/s, C=148, alpha=0.50, eval=-, fps=700, ret=15]\r"
    " 33%|###       | 10000/30000 [00:10<00:20, 700.00frames/s, C=148, alpha=0.50, eval=-12, fps=700, ret=15]\r"
    " 50%|#####     | 15000/30000 [00:15<00:15, 700.00frames/s, C=148, alpha=0.50, eval=-12, fps=700, ret=15]\n"
    " 67%|######    | 20000/30000 [00:20<00:10, 700.00frames/s, C=150, alpha=0.50, eval=-12, fps=700, ret=40]\r"
    " 67%|######    | 20000/30000 [00:20<00:10, 700.00frames/s, C=150, alpha=0.50, eval=2888, fps=700, ret=40]\r"
    "100%|##########| 30000/30000 [00:30<00:00, 700.00frames/s, C=150, alpha=0.00, eval=2888, fps=700, ret=40]\r"
    "100%|##########| 30000/30000 [00:30<00:00, 700.00frames/s, C=150, alpha=0.00, eval=368, fps=700, ret=40]\n"
)


def make_run(tmp_path, final=368.2, best=2887.6):
    run_dir = tmp_path / "seed0"
    run_dir.mkdir()
    (run_dir / "config.yaml").write_text(yaml.safe_dump({"eval": {"every_frames": 10000}}))
    summary = {"frames": 30000, "final_eval_return": final, "best_eval_return": best}
    (run_dir / "summary.json").write_text(json.dumps(summary))
    (run_dir / "campaign.log").write_text(LOG)
    return run_dir


def test_curve_is_the_last_line_at_each_evaluation():
    assert progress_evals.eval_curve(LOG, 10000) == [(10000, -12.0), (20000, 2888.0), (30000, 368.0)]
    # an evaluation equal to the one before it is still read at its own frame count
    assert progress_evals.eval_curve(LOG.replace("eval=2888", "eval=-12"), 10000)[1] == (20000, -12.0)
    # batches that do not divide the interval: the evaluation sits on the first batch past each multiple
    shifted = LOG.replace("10000/30000", "12000/30000").replace("20000/30000", "21000/30000")
    assert progress_evals.eval_curve(shifted, 10000) == [(12000, -12.0), (21000, 2888.0), (30000, 368.0)]
    # a resumed run appends from its checkpoint: its later lines win
    resumed = LOG + LOG.split("\n", 1)[1].replace("eval=368", "eval=400")
    assert progress_evals.eval_curve(resumed, 10000)[-1] == (30000, 400.0)


def test_rebuild_writes_a_results_copy_that_read_scalar_reads(tmp_path):
    run_dir = make_run(tmp_path)
    assert progress_evals.main([str(run_dir)]) == 0
    assert read_scalar(run_dir, "eval/return") == [(10000, -12.0), (20000, 2888.0), (30000, 368.0)]
    with pytest.raises(SystemExit, match="already has its logged scalars"):
        progress_evals.main([str(run_dir)])


def test_rebuild_refuses_a_log_that_misses_an_evaluation(tmp_path):
    run_dir = make_run(tmp_path)
    (run_dir / "campaign.log").write_text(LOG.split("\n", 1)[1])  # the lines up to 15000 frames are gone
    with pytest.raises(SystemExit, match="shows 2 evaluations, the run made 3"):
        progress_evals.main([str(run_dir)])
    assert not (run_dir / "scalars.csv").exists()


def test_rebuild_refuses_a_curve_that_disagrees_with_the_summary(tmp_path):
    run_dir = make_run(tmp_path, best=3000.0)
    with pytest.raises(SystemExit, match="best_eval_return 2888.0, summary.json 3000.0"):
        progress_evals.main([str(run_dir)])
    assert not (run_dir / "scalars.csv").exists()
