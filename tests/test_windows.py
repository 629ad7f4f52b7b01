"""``benchmarks/windows.py``: a run's diagnostics per window of frames, against hand-computed values."""

from __future__ import annotations

import math

import pytest
from benchmark_scripts import load_benchmark

windows = load_benchmark("windows")


def write(run_dir, tag, rows):
    path = run_dir / "logs" / "scalars" / f"{tag}.csv"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(f"{frame},{value}\n" for frame, value in rows))


def test_windows_reduce_each_tag_over_its_frames(tmp_path):
    write(tmp_path, "eval/return", [(10, 1.0), (20, 3.0), (30, 10.0)])
    write(tmp_path, "train/dense_return", [(5, 4.0), (15, 7.0), (25, -1.0)])
    write(tmp_path, "teacher/threshold", [(20, 5.0), (21, 6.0)])
    write(tmp_path, "d/accuracy_agent", [(20, 0.5), (20, 1.0)])
    write(tmp_path, "d/logit_agent_std", [(20, 2.0), (40, 1.0)])  # the logit reward's spread on agent rows
    table = windows.windows(tmp_path, 20)
    assert [row["frames"] for row in table] == [20, 40]  # (0, 20] and (20, 40]: frame 20 is in the first
    first, second = table
    assert first["eval"] == 2.0 and second["eval"] == 10.0  # means
    assert first["train max"] == 7.0 and second["train max"] == -1.0  # maxima
    assert first["C"] == 5.0 and second["C"] == 6.0
    assert first["D acc agent"] == 0.75 and math.isnan(second["D acc agent"])
    assert first["logit agent std"] == 2.0 and second["logit agent std"] == 1.0
    assert math.isnan(first["GP"])  # not logged
    lines = windows.markdown(table, 20).splitlines()
    assert lines[0].startswith(
        "| frames | eval | train max | C | promoted | alpha | D acc teacher | D acc agent | critic reward |"
    )
    assert lines[2].startswith("| 0-0.02k | 2 | 7 | 5 | - |")
    assert lines[3].startswith("| 0.02-0.04k | 10 | -1 | 6 | - |")


def test_frame_0_is_in_the_first_window(tmp_path):
    write(tmp_path, "eval/return", [(0, 49.0)])  # an offline run: one evaluation, at frame 0
    write(tmp_path, "d/skipped", [(0, 0.5), (10, 1.0)])
    (row,) = windows.windows(tmp_path, 20)
    assert row["frames"] == 20 and row["eval"] == 49.0 and row["D skipped"] == 0.75


def test_results_copy_and_cli(tmp_path, capsys):
    (tmp_path / "scalars.csv").write_text("tag,frames,value\neval/return,1000,123.456\nalpha,1000,0.5\n")
    windows.main([str(tmp_path), "--window", "1000"])
    out = capsys.readouterr().out
    assert "| 0-1k | 123 | - | - | - | 0.5 |" in out
    with pytest.raises(SystemExit):
        windows.main([str(tmp_path / "missing")])
    with pytest.raises(SystemExit):
        windows.main([str(tmp_path), "--window", "0"])
