"""The operator page's reliability is the estimate reward training acts on: from the
other people's answers (the peer estimator whose flags `--crowd-weighting drop` uses),
with the evidence it rests on and the flag's threshold."""

from __future__ import annotations

from seqrank.feedback.peer_reliability import estimate_from_peers
from seqrank.feedback.reliability import evidence_rows
from seqrank.labelling.crowd_report import _reliability, _reliability_fields


def _rows(pairs: int) -> list[dict]:
    """alice and bob say "first" on every pair, carol "second" on all but every 5th."""
    rows = []
    for k in range(pairs):
        first, second = 2 * k, 2 * k + 1
        for name in ("alice", "bob"):
            rows.append({"first": first, "second": second, "answer": "first", "annotator": name})
        carol = "first" if k % 5 == 0 else "second"
        rows.append({"first": first, "second": second, "answer": carol, "annotator": "carol"})
    return rows


def test_the_page_flags_whom_training_drops_and_says_what_it_rests_on():
    rows = _rows(40)
    shown = {name: _reliability_fields(r) for name, r in _reliability(rows).items()}
    assert shown["carol"]["flagged"] and not shown["alice"]["flagged"]
    assert not shown["bob"]["flagged"]
    assert shown["carol"]["rests_on"] == 40
    assert shown["carol"]["flag_below"] > shown["carol"]["reliability"]
    evidence = evidence_rows((r["first"], r["second"], r["answer"], r["annotator"], None)
                             for r in rows)  # fmt: skip
    trained = estimate_from_peers(evidence)
    assert {n: r.flagged for n, r in trained.items()} == {n: s["flagged"] for n, s in shown.items()}
    assert {n: r.estimate for n, r in trained.items()} == {
        n: s["reliability"] for n, s in shown.items()
    }


def test_answers_per_minute_count_the_time_spent_answering_not_the_breaks():
    from seqrank.labelling.crowd_report import BREAK_S, answers_per_minute

    first = [10.0 * k for k in range(7)]  # an answer every 10 s: 6 a minute
    after_a_break = [first[-1] + 3600.0 + 10.0 * k for k in range(7)]  # an hour stopped
    assert answers_per_minute(first) == answers_per_minute(first + after_a_break) == 6.0
    assert answers_per_minute([0.0, BREAK_S]) == 60.0 / BREAK_S  # (a long pause, not a break)
    assert answers_per_minute([5.0]) is None and answers_per_minute([0.0, 3 * BREAK_S]) is None
