"""scripts/sb3_evidence.py at a tiny size: one (method, seed) a call, resumable by chunks,
finished runs skipped, folders `seqrank report` collects."""

from __future__ import annotations

import json

from seqrank.report.collect import collect_runs
from support.scripts import load_script

evidence = load_script("sb3_evidence")

TASK = "support.sb3_envs:make_line"
TINY = ["--task", TASK, "--steps", "600", "--chunk", "300", "--max-feedback", "20", "--tiny"]


def test_a_run_continues_by_chunks_and_is_skipped_once_finished(tmp_path):
    args = ["--out", str(tmp_path), "--method", "root", "--seed", "1", *TINY]
    assert "stopped at step 300" in evidence.run([*args, "--chunks", "1"])
    assert "finished, eval return" in evidence.run(args)
    assert "finished already" in evidence.run(args)
    assert "finished, eval return" in evidence.run(
        ["--out", str(tmp_path), "--method", "true-reward", "--seed", "1", *TINY]
    )
    runs = {run.path.name: run for run in collect_runs(tmp_path)}
    root = runs["root_sb3-sac_oracle_seed1"]
    assert root.backbone == "sb3-sac" and root.finished and root.steps == 600
    assert [step for step, _, _ in root.curve] == [300, 600]
    assert sum(row["questions"] for row in root.feedback) == 20
    assert runs["true-reward_sb3-sac_seed1"].reward == "true"
    config = json.loads((root.path / "config.json").read_text())
    assert config["scheme"] == "root" and config["max_feedback"] == 20
