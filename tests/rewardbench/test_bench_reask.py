"""The reward benchmark's crowd weighting `reask` (issue 49, item 3): its rows, its
command, and the other weightings' records as they were before it existed."""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace

import pytest
from test_reward_bench import SMALL, synthetic_pool

from seqrank.cli import main
from seqrank.rewardbench.bench import RewardNet, _CellRun, run_cell
from seqrank.rewardbench.cells import Cell
from seqrank.rewardbench.grid import read_rows
from seqrank.rewardbench.pool import save_pool
from seqrank.rewardbench.summary import method

CROWD = "crowd:oracle+mistake+mistake,eps_mistake=0.3,name=bad"
WRONG = "crowd:oracle+oracle+mistake,eps_mistake=1.0,name=bad"
EVIDENCE = replace(SMALL, overlap_until=20)


def stored_digest(weighting: str) -> str:
    """What a cell's sessions store up to 30 questions (answers, pairs, labels, who gave
    them, what trains, the people's time), hashed."""
    run = _CellRun(
        synthetic_pool(), Cell("sequential", CROWD, 0, weighting=weighting), EVIDENCE, None
    )
    run.ask_until(30)
    stored = run.labels
    kept = stored.kept()
    values = [stored.crowd_answers, stored.labels, stored.annotator, stored.first, stored.second]
    values += [stored.asked, stored.inferred, kept, run.tally.person_seconds]
    return hashlib.sha256(json.dumps(values).encode()).hexdigest()[:16]


@pytest.mark.parametrize(
    ("weighting", "digest"),
    # computed before `reask` existed (commit 41d5c0f): the same seed, the same records
    [
        ("drop", "4ab3dde764697d77"),
        ("none", "0857707181b5aaef"),
        ("reliability", "0857707181b5aaef"),
    ],
)
def test_the_other_weightings_store_what_they_stored_before_reask(weighting, digest):
    assert stored_digest(weighting) == digest


def test_a_reask_cell_asks_the_flagged_members_questions_again_at_more_person_time():
    pool, quick = synthetic_pool(), replace(EVIDENCE, net=RewardNet(hidden=16, epochs=3))
    cells = {w: Cell("sequential", WRONG, 0, weighting=w) for w in ("drop", "reask")}
    rows = {w: run_cell(pool, cell, quick) for w, cell in cells.items()}
    for reask, drop in zip(rows["reask"], rows["drop"], strict=True):
        assert (reask["weighting"], method(reask)) == ("reask", "plain+reasked")
        assert reask["questions"] == drop["questions"]  # re-asks spend no question
        assert "reasks" not in drop
    # nobody is flagged before the first session; by the second, the wrong member is
    first, last = rows["reask"]
    assert first["reasks"] == 0 and first["person_minutes"] == rows["drop"][0]["person_minutes"]
    assert last["members"]["bad"]["flagged"] and last["reasks"] > 0
    assert last["person_minutes"] > rows["drop"][-1]["person_minutes"]


def test_the_command_takes_reask(tmp_path, capsys):
    pool_file = save_pool(synthetic_pool(), tmp_path / "pool.npz")
    out = tmp_path / "bench"
    args = ["reward-bench", "run", "--pool", str(pool_file), "--schemes", "sequential"]
    args += ["--teachers", WRONG, "--weightings", "drop,reask", "--overlap-until", "20"]
    args += ["--seeds", "1", "--budgets", "20", "--session-questions", "10", "--out", str(out)]
    assert main([*args, "--heldout-segments", "40", "--reward-epochs", "3", "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert sorted(r["weighting"] for r in read_rows(out / "rows.jsonl")) == ["drop", "reask"]
    assert "| plain+reasked |" in printed and "| plain+dropped |" in printed
