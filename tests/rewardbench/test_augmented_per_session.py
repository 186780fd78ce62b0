"""`scripts/augmented_per_session.py`: each seed's longest row gives its sessions' counts,
and theory's expectation is the paper's for root (D.6: 91.61 at 100 questions)."""

from __future__ import annotations

import json

import pytest

from support.scripts import load_script


@pytest.fixture(scope="module")
def script():
    return load_script("augmented_per_session")


def test_theory_matches_the_papers_random_order_expectation_for_root(script):
    assert script.expected_augmented("root", 100) == pytest.approx(91.61, abs=0.01)
    # a session of one question infers nothing
    assert script.expected_augmented("sequential", 1) == pytest.approx(0.0)


def _row(scheme, seed, questions, sessions, order="collection"):
    return {
        "task": "t", "scheme": scheme, "order": order, "seed": seed,
        "questions": questions, "session_inferred": sessions,
    }  # fmt: skip


def test_each_seed_counts_once_with_its_longest_row(script, tmp_path):
    rows = [
        _row("root", 0, 10, [4]),
        _row("root", 0, 20, [4, 8]),
        _row("root", 1, 20, [6, 2]),
        _row("pairwise", 0, 20, [0, 0]),
    ]
    (tmp_path / "rows.jsonl").write_text("\n".join(json.dumps(r) for r in rows))
    (tmp_path / "settings.json").write_text(json.dumps({"session_questions": 10}))
    grouped = script.last_rows(tmp_path / "rows.jsonl")
    assert grouped == {("t", "root", "collection"): [[4, 8], [6, 2]]}
    lines = script.table(tmp_path)
    first, second = (line for line in lines if line.startswith("| t | root"))
    assert "| 1 | 2 | 5.0 [" in first  # (4 + 6) / 2 over two seeds
    assert "| 2 | 2 | 5.0 [" in second
