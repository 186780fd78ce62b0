"""The crowd's tables from a reward-benchmark grid (results/crowd/README.md).

    python scripts/crowd_evidence.py results/crowd/bench > results/crowd/tables.md
    python scripts/crowd_evidence.py --uses results/crowd/uses > results/crowd/uses.md

`--uses` (issue 49): grids of crowds with one bad member (named `bad`) or none, under
several uses of the estimate (`--weightings`): each use's accuracy, its paired gain over
labels as answered, each member's flag rate (the estimator's and the one before it, the
reward model a voter) and interval coverage, and the answers the people gave.

Reads the grid's rows.jsonl: each member alone (its own teacher spec) and the crowd, with
and without reliability weighting, on the same pool and seeds. Writes three tables:
held-out accuracy per question budget; the same at the largest budget against person- and
wall-clock minutes; and each member's estimated reliability against its true error rate.
A member alone answers at the crowd's pace (`ANSWER_SECONDS` an answer, one after another),
so its person-minutes are its wall-clock minutes.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.feedback.peer_reliability import FLAG_AFTER, FLAG_BELOW
from seqrank.rewardbench.intervals import bounded_interval

ANSWER_SECONDS = 3.0  # a crowd member's default answer time (`time=` of crowd:...)
ALONE = {  # the crowd's members as teachers of their own
    "oracle": "oracle",
    "mistake": "mistake",
    "mistake,eps_mistake=0.3": "noisy (mistake, eps_mistake=0.3)",
}


def method_of(row: dict[str, Any]) -> str:
    if row["teacher"].startswith("crowd:"):
        return f"crowd, {'weighted' if row['weighting'] == 'reliability' else 'unweighted'}"
    return f"{ALONE.get(row['teacher'], row['teacher'])} alone"


def _ci(values: list[float], low: float = 0.0, high: float = 1.0) -> str:
    if not values:
        return "-"
    mean, lo, hi = bounded_interval(values, low, high)
    if lo is None or hi is None:
        return f"{mean:.3f}"
    return f"{mean:.3f} [{lo:.3f}, {hi:.3f}]"


def accuracy_table(rows: list[dict[str, Any]]) -> list[str]:
    cells: dict[tuple[str, int, str], list[float]] = defaultdict(list)
    for row in rows:
        cells[(row["scheme"], row["questions"], method_of(row))].append(row["accuracy"])
    methods = sorted({m for _, _, m in cells}, key=lambda m: (not m.startswith("crowd"), m))
    lines = [
        "| scheme | questions | " + " | ".join(methods) + " |",
        "|---|---|" + "---|" * len(methods),
    ]
    for scheme, questions in sorted({(s, q) for s, q, _ in cells}):
        values = [_ci(cells.get((scheme, questions, m), [])) for m in methods]
        lines.append(f"| {scheme} | {questions} | " + " | ".join(values) + " |")
    return lines


def paired_gain(rows: list[dict[str, Any]]) -> list[str]:
    """Weighted minus unweighted accuracy, paired by seed (the same answers, trained twice)."""
    crowd = [r for r in rows if r["teacher"].startswith("crowd:")]
    by: dict[tuple[str, int], dict[str, dict[int, float]]] = defaultdict(lambda: defaultdict(dict))
    for row in crowd:
        by[(row["scheme"], row["questions"])][row["weighting"]][row["seed"]] = row["accuracy"]
    lines = ["| scheme | questions | weighted - unweighted [95% CI] | seeds |", "|---|---|---|---|"]
    for (scheme, questions), sides in sorted(by.items()):
        seeds = sorted(set(sides["reliability"]) & set(sides["none"]))
        gains = [sides["reliability"][s] - sides["none"][s] for s in seeds]
        if gains:
            lines.append(f"| {scheme} | {questions} | {_ci(gains, -1.0, 1.0)} | {len(seeds)} |")
    return lines


def time_table(rows: list[dict[str, Any]]) -> list[str]:
    largest = max(row["questions"] for row in rows)
    cells: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        if row["questions"] == largest:
            cells[(row["scheme"], method_of(row))].append(row)
    lines = [
        f"| scheme | method ({largest} questions) | person-minutes | wall-clock minutes "
        "| accuracy [95% CI] | accuracy per person-minute |",
        "|---|---|---|---|---|---|",
    ]
    for (scheme, method), group in sorted(cells.items()):
        if method.startswith("crowd"):
            person = float(np.mean([r["person_minutes"] for r in group]))
            wall = float(np.mean([r["crowd_minutes"] for r in group]))
        else:
            person = wall = float(np.mean([r["answered"] for r in group])) * ANSWER_SECONDS / 60
        accuracy = [r["accuracy"] for r in group]
        per_minute = float(np.mean(accuracy)) / person
        lines.append(
            f"| {scheme} | {method} | {person:.2f} | {wall:.2f} | {_ci(accuracy)} "
            f"| {per_minute:.3f} |"
        )
    return lines


def reliability_table(rows: list[dict[str, Any]]) -> list[str]:
    largest = max(row["questions"] for row in rows)
    cells: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        if row.get("members") and row["questions"] == largest and row["weighting"] != "none":
            for name, member in row["members"].items():
                cells[(row["scheme"], name)].append(member)
    lines = [
        f"| scheme | member | true accuracy (1 - error rate) | estimated reliability at "
        f"{largest} questions [95% CI] | mean interval | answers it rests on | flagged |",
        "|---|---|---|---|---|---|---|",
    ]
    for (scheme, name), members in sorted(cells.items()):
        truth = 1 - float(np.mean([m["true_error_rate"] for m in members]))
        estimate = _ci([m["estimate"] for m in members])
        low = float(np.mean([m["low"] for m in members]))
        high = float(np.mean([m["high"] for m in members]))
        answers = float(np.mean([m["answers"] for m in members]))
        flagged = sum(bool(m["flagged"]) for m in members)
        lines.append(
            f"| {scheme} | {name} | {truth:.3f} | {estimate} | [{low:.2f}, {high:.2f}] "
            f"| {answers:.0f} | {flagged}/{len(members)} |"
        )
    return lines


def crowd_of(teacher: str) -> str:
    """A crowd's short name: its bad member's flips, or all good."""
    for member in teacher.removeprefix("crowd:").split("+"):
        knobs = dict(part.split("=", 1) for part in member.split(",")[1:])
        if knobs.get("name") in ("bad", "noisy"):
            flips = float(knobs.get("eps_mistake", 0.1))
            return "bad always wrong" if flips == 1.0 else f"bad wrong {flips:.0%}"
    return "all good"


def _crowd_rows(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{**r, "crowd": crowd_of(r["teacher"])} for r in rows if r.get("members")]


def _paired_gains(rows: list[dict[str, Any]]) -> dict[tuple[str, str, int], dict[str, Any]]:
    """For each crowd, scheme and budget: accuracy as answered by seed, and each use's
    gain over it, paired by seed (the same answers)."""
    by: dict[tuple[str, str, int], dict[str, dict[int, float]]] = defaultdict(
        lambda: defaultdict(dict)
    )
    for row in _crowd_rows(rows):
        key = (row["crowd"], row["scheme"], row["questions"])
        by[key][row["weighting"]][row["seed"]] = row["accuracy"]
    cells: dict[tuple[str, str, int], dict[str, Any]] = {}
    for key, sides in sorted(by.items()):
        plain = sides.get("none", {})
        gains = {
            use: [side[s] - plain[s] for s in sorted(set(side) & set(plain))]
            for use, side in sides.items()
            if use != "none"
        }
        cells[key] = {"none": list(plain.values()), "gains": gains}
    return cells


def use_gain_table(rows: list[dict[str, Any]]) -> list[str]:
    """Each use's accuracy minus labels as answered, paired by seed (the same answers)."""
    cells = _paired_gains(rows)
    uses = sorted({use for cell in cells.values() for use in cell["gains"]})
    lines = [
        "| crowd | scheme | questions | as answered | "
        + " | ".join(f"{use} - as answered [95% CI] (seeds)" for use in uses)
        + " |",
        "|---|---|---|---|" + "---|" * len(uses),
    ]
    for (crowd, scheme, questions), cell in cells.items():
        gains = [cell["gains"].get(use, []) for use in uses]
        shown = [f"{_ci(g, -1.0, 1.0)} ({len(g)})" if g else "-" for g in gains]
        lines.append(
            f"| {crowd} | {scheme} | {questions} | {_ci(cell['none'])} | "
            + " | ".join(shown)
            + " |"
        )
    return lines


GOAL_QUESTIONS = 100  # issue 49's goals are read at this budget
GOAL_USE = "drop"  # the default use of the estimate


def goals_table(rows: list[dict[str, Any]]) -> list[str]:
    """Issue 49's goals against the rows: the default use's gain with a bad member (its
    95% interval above 0 at three schemes or more), its cost with an all-good crowd (no
    mean below -0.01 at any budget), and the flags by the goal budget (the bad member in 9
    of 10 seeds or more, each good member in at most 1 of 10)."""
    cells = _paired_gains(rows)
    lines = ["| goal | crowd | measured | met |", "|---|---|---|---|"]
    for crowd in sorted({c for c, _, _ in cells} - {"all good"}):
        above = sorted(
            scheme
            for (c, scheme, q), cell in cells.items()
            if c == crowd and q == GOAL_QUESTIONS and _lower(cell["gains"].get(GOAL_USE)) > 0
        )
        lines.append(
            f"| {GOAL_USE} above as answered at {GOAL_QUESTIONS} questions (interval above 0) "
            f"at 3 schemes or more | {crowd} | {len(above)}: {', '.join(above) or 'none'} "
            f"| {_yes(len(above) >= 3)} |"
        )
    costs = [
        (float(np.mean(cell["gains"][GOAL_USE])), scheme, q)
        for (c, scheme, q), cell in cells.items()
        if c == "all good" and cell["gains"].get(GOAL_USE)
    ]
    if costs:
        worst, scheme, q = min(costs)
        lines.append(
            f"| {GOAL_USE} costs no more than 0.01 anywhere (mean) | all good "
            f"| lowest {worst:+.3f} ({scheme}, {q} questions) | {_yes(worst >= -0.01)} |"
        )
    for bad, rule in ((True, "the bad member flagged in 9 of 10 or more"),
                      (False, "each good member flagged in at most 1 of 10")):  # fmt: skip
        rates = _flag_rates(rows, bad)
        if rates:
            rate, where = (min if bad else max)(rates)
            met = rate >= 0.9 if bad else rate <= 0.1
            lines.append(
                f"| {rule}, at {GOAL_QUESTIONS} questions | every crowd | "
                f"{'lowest' if bad else 'highest'} {rate:.0%} ({where}) | {_yes(met)} |"
            )
    return lines


def _yes(met: bool) -> str:
    return "yes" if met else "no"


def _lower(gains: list[float] | None) -> float:
    if not gains:
        return float("-inf")
    low = bounded_interval(gains, -1.0, 1.0)[1]
    return float("-inf") if low is None else low


def _flag_rates(rows: list[dict[str, Any]], bad: bool) -> list[tuple[float, str]]:
    """The share of seeds each member (bad ones, or good ones) is flagged in at the goal
    budget, by crowd, scheme and member, with where."""
    flags: dict[tuple[str, str, str], list[bool]] = defaultdict(list)
    for row in _crowd_rows(rows):
        if row["weighting"] == "none" and row["questions"] == GOAL_QUESTIONS:
            for name, member in row["members"].items():
                if (name in ("bad", "noisy")) == bad:
                    flags[(row["crowd"], row["scheme"], name)].append(_flagged(member))
    return [
        (sum(f) / len(f), f"{sum(f)}/{len(f)}: {crowd}, {scheme}, {name}")
        for (crowd, scheme, name), f in sorted(flags.items())
    ]


def flag_table(rows: list[dict[str, Any]]) -> list[str]:
    """Each member's flag rate over seeds, by the estimator and by the one before it
    (the reward model a voter), with the true accuracy and the estimate's interval
    coverage of it. One row per seed: the cells as answered (every use asks the same)."""
    cells: dict[tuple[str, str, int, str], list[dict[str, Any]]] = defaultdict(list)
    for row in _crowd_rows(rows):
        if row["weighting"] == "none":
            for name, member in row["members"].items():
                cells[(row["crowd"], row["scheme"], row["questions"], name)].append(member)
    lines = [
        "| crowd | scheme | questions | member | true accuracy | estimate [95% CI over seeds] "
        f"| answers checked by others | flagged (below {FLAG_BELOW}) | interval covers the truth "
        "| flagged, model a voter |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (crowd, scheme, questions, name), members in sorted(cells.items()):
        truths = [1 - m["true_error_rate"] for m in members if m["true_error_rate"] is not None]
        covered = [
            m["low"] <= 1 - m["true_error_rate"] <= m["high"]
            for m in members
            if m["true_error_rate"] is not None
        ]
        old = [m["with_model"]["flagged"] for m in members if "with_model" in m]
        lines.append(
            f"| {crowd} | {scheme} | {questions} | {name} | {np.mean(truths):.3f} "
            f"| {_ci([m['estimate'] for m in members])} "
            f"| {np.mean([m['answers'] for m in members]):.0f} "
            f"| {sum(_flagged(m) for m in members)}/{len(members)} "
            f"| {sum(covered)}/{len(covered)} | {sum(old)}/{len(old)} |"
        )
    return lines


THRESHOLDS = (0.78, 0.80, 0.82, 0.84, 0.86)


def _flagged(member: dict[str, Any]) -> bool:
    """Whether the member's recorded estimate is flagged at today's threshold (rows made
    before the threshold moved from 0.82 to 0.84 recorded their flag at 0.82)."""
    return member["answers"] >= FLAG_AFTER and member["estimate"] < FLAG_BELOW


def threshold_table(rows: list[dict[str, Any]]) -> list[str]:
    """The flag's error rates had it been set elsewhere: the share of the bad members an
    estimate below each threshold would flag (with as many answers checked as the flag
    needs), and of the good ones, over every scheme and seed, by question budget."""
    counts: dict[tuple[int, bool], list[tuple[float, int]]] = defaultdict(list)
    for row in _crowd_rows(rows):
        if row["weighting"] == "none":
            for name, member in row["members"].items():
                bad = name in ("bad", "noisy")
                counts[(row["questions"], bad)].append((member["estimate"], member["answers"]))
    header = " | ".join(f"below {t:.2f}: bad / good" for t in THRESHOLDS)
    lines = [f"| questions | {header} |", "|---|" + "---|" * len(THRESHOLDS)]
    for questions in sorted({q for q, _ in counts}):
        cells = []
        for threshold in THRESHOLDS:
            rates = []
            for bad in (True, False):
                found = counts.get((questions, bad), [])
                flagged = sum(e < threshold and n >= FLAG_AFTER for e, n in found)
                rates.append(f"{flagged}/{len(found)}")
            cells.append(" / ".join(rates))
        lines.append(f"| {questions} | " + " | ".join(cells) + " |")
    return lines


def person_answers_table(rows: list[dict[str, Any]]) -> list[str]:
    """The answers the people gave (second opinions included) per question asked."""
    cells: dict[tuple[str, str, int], list[float]] = defaultdict(list)
    for row in _crowd_rows(rows):
        if row["weighting"] == "none":
            answers = row["person_minutes"] * 60 / ANSWER_SECONDS
            cells[(row["crowd"], row["scheme"], row["questions"])].append(answers)
    lines = [
        "| crowd | scheme | questions | person-answers (mean) | per question |",
        "|---|---|---|---|---|",
    ]
    for (crowd, scheme, questions), answers in sorted(cells.items()):
        mean = float(np.mean(answers))
        lines.append(f"| {crowd} | {scheme} | {questions} | {mean:.0f} | {mean / questions:.2f} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("grid", type=Path, help="the grid's folder (holds rows.jsonl)")
    parser.add_argument(
        "--uses", action="store_true", help="issue 49's tables: uses, flags, person-answers"
    )
    args = parser.parse_args()
    rows = [json.loads(line) for line in (args.grid / "rows.jsonl").read_text().splitlines()]
    sections = [
        ("Held-out accuracy by question budget (mean [95% CI] over seeds)", accuracy_table),
        ("Reliability weighting: the paired gain", paired_gain),
        ("Human time at the largest budget", time_table),
        ("Each member's estimated reliability against the truth", reliability_table),
    ]
    if args.uses:
        sections = [
            (
                "Each use of the estimate against labels as answered (paired by seed)",
                use_gain_table,
            ),
            ("Flags: each member, by question budget", flag_table),
            (
                "The flag's error rates at other thresholds (every crowd and scheme)",
                threshold_table,
            ),
            ("What the people answered (second opinions included)", person_answers_table),
            ("Issue 49's goals", goals_table),
        ]
    for title, table in sections:
        print(f"### {title}\n")
        print("\n".join(table(rows)) + "\n")


if __name__ == "__main__":
    main()
