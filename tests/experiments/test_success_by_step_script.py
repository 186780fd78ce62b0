"""`scripts/success_by_step.py`: one row a run, the last evaluation of a step counting
(a resumed run repeats its last one), a run without a summary shown as running."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from support.scripts import load_script


@pytest.fixture(scope="module")
def script():
    return load_script("success_by_step")


def _run(folder: Path, evals: list[tuple[int, float]], summary: dict | None) -> None:
    folder.mkdir(parents=True)
    rows = [{"step": s, "kind": "eval", "eval_success_rate": r} for s, r in evals]
    rows.insert(1, {"step": 5, "kind": "train", "critic_loss": 1.0})
    (folder / "metrics.jsonl").write_text("\n".join(json.dumps(r) for r in rows))
    if summary is not None:
        (folder / "summary.json").write_text(json.dumps(summary))


def test_rows_take_each_steps_last_evaluation_and_mark_running_runs(script, tmp_path):
    done = {"wall_seconds": 120.0, "inferred": 7, "inferred_wrong": 1}
    _run(
        tmp_path / "t" / "root_pebble_oracle_seed3",
        [(10_000, 0.0), (20_000, 30.0), (20_000, 40.0)],
        done,
    )
    _run(tmp_path / "t" / "true-reward_seed0", [(10_000, 10.0)], None)
    header, _, root, true = script.table(tmp_path)
    assert header.startswith("| run | 10K | 20K | wall (min) |")
    assert root == "| root, seed 3 | 0 | 40 | 2.0 | 7 (1) |"
    assert true == "| true reward, seed 0 | 10 |  | running | 0 |"
