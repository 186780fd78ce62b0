"""scripts/crowd_evidence.py's goals table (issue 49): each goal read from the rows it
names, met and missed alike."""

from __future__ import annotations

from typing import Any

import pytest

from support.scripts import load_script

BAD = "crowd:oracle+mistake+mistake,eps_mistake=0.3,name=bad"
GOOD = "crowd:oracle+mistake+mistake"
SCHEMES = ("pairwise", "sequential", "root", "ranked")


@pytest.fixture(scope="module")
def evidence():
    return load_script("crowd_evidence")


def member(estimate: float, answers: int = 60, truth: float = 0.9) -> dict[str, Any]:
    return {
        "estimate": estimate,
        "answers": answers,
        "low": estimate - 0.05,
        "high": estimate + 0.05,
        "true_error_rate": 1 - truth,
        "flagged": False,
    }


def row(teacher, scheme, questions, seed, weighting, accuracy, members) -> dict[str, Any]:
    return dict(
        teacher=teacher,
        scheme=scheme,
        questions=questions,
        seed=seed,
        weighting=weighting,
        accuracy=accuracy,
        members=members,
        person_minutes=1.0,
    )


def grid(gain_at: dict[str, float], good_cost: float, good_flags: int) -> list[dict[str, Any]]:
    """Ten seeds at 100 questions: with the bad member, drop gains `gain_at[scheme]` (with
    a little spread); with an all-good crowd it costs `good_cost` at pairwise; a good member
    of the bad crowd is flagged (below 0.84) in `good_flags` of the ten seeds."""
    rows = []
    for seed in range(10):
        wobble = 0.004 * (seed % 3 - 1)
        for scheme in SCHEMES:
            flagged_good = scheme == "pairwise" and seed < good_flags
            bad_members = {
                "oracle": member(0.98, truth=1.0),
                "mistake": member(0.80 if flagged_good else 0.92),
                "bad": member(0.70, truth=0.7),
            }
            good_members = {"oracle": member(0.98, truth=1.0), "mistake": member(0.92)}
            cost = good_cost if scheme == "pairwise" else 0.0
            rows += [
                row(BAD, scheme, 100, seed, "none", 0.7, bad_members),
                row(BAD, scheme, 100, seed, "drop", 0.7 + gain_at[scheme] + wobble, bad_members),
                row(GOOD, scheme, 100, seed, "none", 0.8, good_members),
                row(GOOD, scheme, 100, seed, "drop", 0.8 + cost + wobble, good_members),
            ]
    return rows


def verdicts(evidence, rows) -> dict[str, tuple[str, str]]:
    lines = evidence.goals_table(rows)[2:]
    cells = [line.strip("| ").split(" | ") for line in lines]
    return {f"{goal[:24]}, {crowd}": (measured, met) for goal, crowd, measured, met in cells}


def test_goals_met_are_said_met(evidence):
    gains = dict(pairwise=0.05, sequential=0.05, root=0.05, ranked=0.0)
    said = verdicts(evidence, grid(gains, good_cost=-0.005, good_flags=1))
    assert said["drop above as answered a, bad wrong 30%"] == (
        "3: pairwise, root, sequential",
        "yes",
    )
    assert said["drop costs no more than , all good"] == (
        "lowest -0.005 (pairwise, 100 questions)",
        "yes",
    )
    assert said["the bad member flagged i, every crowd"][1] == "yes"
    assert said["each good member flagged, every crowd"] == (
        "highest 10% (1/10: bad wrong 30%, pairwise, mistake)",
        "yes",
    )


def test_goals_missed_are_said_missed_with_by_how_much(evidence):
    gains = dict(pairwise=0.05, sequential=0.05, root=0.0, ranked=0.0)
    said = verdicts(evidence, grid(gains, good_cost=-0.02, good_flags=2))
    assert said["drop above as answered a, bad wrong 30%"] == ("2: pairwise, sequential", "no")
    assert said["drop costs no more than , all good"] == (
        "lowest -0.020 (pairwise, 100 questions)",
        "no",
    )
    assert said["each good member flagged, every crowd"] == (
        "highest 20% (2/10: bad wrong 30%, pairwise, mistake)",
        "no",
    )


def test_a_bad_member_short_of_checked_answers_is_not_counted_flagged(evidence):
    rows = grid(dict.fromkeys(SCHEMES, 0.05), good_cost=0.0, good_flags=0)
    for r in rows:
        if r["teacher"] == BAD and r["seed"] < 2:
            r["members"] = {**r["members"], "bad": member(0.70, answers=evidence.FLAG_AFTER - 1)}
    measured, met = verdicts(evidence, rows)["the bad member flagged i, every crowd"]
    assert measured.startswith("lowest 80% (8/10") and met == "no"
