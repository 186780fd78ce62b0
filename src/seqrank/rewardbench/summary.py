"""The reward benchmark's table and curves, from its rows (one per cell and budget)."""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import numpy as np

from seqrank.feedback.schemes import SchemeName
from seqrank.rewardbench.cells import weighs_labels
from seqrank.rewardbench.intervals import Interval, bounded_interval

MEASURES = {
    "accuracy": "held-out preference accuracy",
    "spearman": "rank correlation (Spearman)",
    "top_accuracy": "accuracy in the top quarter",
    "top_recall": "true top 10% found in the predicted",
    "regret": "regret of the best of 10 (of the range)",
    "inferred_wrong": "wrong inferred labels (fraction)",
}
RANGES = {measure: (0.0, 1.0) for measure in MEASURES} | {"spearman": (-1.0, 1.0)}
# compared seed by seed in effects.md, each difference within twice its measure's range
DIFFERENCES = ("accuracy", "spearman", "top_accuracy", "top_recall", "regret")
Group = tuple[str, str, str, str, int]  # task, teacher, method, scheme, questions


def method(row: dict[str, Any]) -> str:
    """The reward learner, with a suffix per control away from its default: `+checked`
    under noise-aware augmentation, `+no-closure` without closure, `+stop-asked` or
    `+stop-never` for the stop rule, `+collection` for segments in collection order, and
    `+weighted` for a crowd's labels weighted by reliability, `+dropped` for a flagged
    member's labels left out, `+reasked` for those left out and their questions asked
    again of someone else. The names of the defaults
    (full closure, the stop over all labels, uniform order, a crowd's labels as answered)
    are bare, so a report's baseline is the default. Rows written before these axes are
    plain, full, stopped over all, uniform and weighted."""
    name = row.get("learner", "plain")
    augment = row.get("augment", "full")
    name += {"full": "", "none": "+no-closure"}.get(augment, f"+{augment}")
    stop, order = row.get("stop", "all"), row.get("order", "uniform")
    name += "" if stop == "all" else f"+stop-{stop}"
    name += "" if order == "uniform" else f"+{order}"
    weighting = row.get("weighting", "reliability")
    if not weighs_labels(row.get("teacher", "")) or weighting == "none":
        return name
    suffixes = {
        "reliability": "+weighted",
        "drop": "+dropped",
        "reask": "+reasked",
        "soften": "+softened",
    }
    return name + suffixes[weighting]


def summarise(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per task, teacher, learner, scheme and budget: each measure's mean and 95% interval
    (within the measure's range; none for one seed: `intervals.py`)."""
    groups: dict[Group, list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        groups[(row["task"], row["teacher"], method(row), row["scheme"], row["questions"])].append(
            row
        )
    order = [s.value for s in SchemeName]
    summary = []
    for (task, teacher, learner, scheme, questions), members in sorted(
        groups.items(),
        key=lambda item: (*item[0][:3], order.index(item[0][3]), item[0][4]),
    ):
        entry: dict[str, Any] = {
            "task": task,
            "teacher": teacher,
            "learner": learner,
            "scheme": scheme,
            "questions": questions,
            "seeds": len(members),
            "pairs": float(np.mean([m["pairs"] for m in members])),
            "asked_wrong": _mean_of([m.get("asked_wrong") for m in members]),
            # what the questions cost an annotator (None for rows written before)
            "clips": _mean_of([m.get("clips") for m in members]),
            "annotator_seconds": _mean_of([m.get("annotator_seconds") for m in members]),
        }
        for measure in MEASURES:  # (rows written before a measure have none of it)
            values = [m[measure] for m in members if m.get(measure) is not None]
            entry[measure] = bounded_interval(values, *RANGES[measure]) if values else None
        summary.append(entry)
    return summary


def format_table(summary: list[dict[str, Any]], budgets: list[int] | None = None) -> str:
    lines = [
        "| task | teacher | method | questions | scheme | seeds | labelled pairs "
        "| accuracy [95% CI] | Spearman [95% CI] | top-quarter accuracy [95% CI] "
        "| top-10% recall [95% CI] | regret (best of 10) [95% CI] | wrong inferred "
        "| wrong asked | clips | annotator minutes |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for e in summary:
        if budgets is not None and e["questions"] not in budgets:
            continue
        wrong = "-" if e["inferred_wrong"] is None else f"{e['inferred_wrong'][0]:.3f}"
        asked = "-" if e["asked_wrong"] is None else f"{e['asked_wrong']:.3f}"
        lines.append(
            f"| {e['task']} | {e['teacher']} | {e['learner']} | {e['questions']} | {e['scheme']} "
            f"| {e['seeds']} "
            f"| {e['pairs']:.0f} | {_cell(e['accuracy'])} | {_cell(e['spearman'])} "
            f"| {_cell(e['top_accuracy'])} | {_cell(e['top_recall'])} | {_cell(e['regret'])} "
            f"| {wrong} | {asked} | {_number(e.get('clips'), 1, '.0f')} "
            f"| {_number(e.get('annotator_seconds'), 60, '.1f')} |"
        )
    return "\n".join(lines) + "\n"


def _number(value: float | None, unit: float, form: str) -> str:
    return "-" if value is None else format(value / unit, form)


def _mean_of(values: list[float | None]) -> float | None:
    """The mean of the known values (None when there is none)."""
    known = [v for v in values if v is not None]
    return float(np.mean(known)) if known else None


def _cell(value: Interval | None) -> str:
    if value is None:
        return "-"
    mean, low, high = value
    if low is None or high is None:
        return f"{mean:.3f} (n=1)"  # one seed: no interval
    return f"{mean:.3f} [{low:.3f}, {high:.3f}]"


Paired = tuple[str, str, str, int, int]  # task, teacher, scheme, questions, seed


def paired_effects(rows: list[dict[str, Any]], baseline: str = "plain") -> list[dict[str, Any]]:
    """Each method against `baseline` on the same task, teacher, scheme, budget and seed (cells
    of one seed start from the same reward model and share their random streams, so the
    seed-by-seed difference has less noise than two separate means): the mean difference in
    accuracy and Spearman with a 95% interval over seeds (within the differences' range,
    [-1, 1] and [-2, 2]; none for one seed), each side's wrong inferred
    labels, and a verdict. Two rows of one method and cell (merged folders, two pools of a
    task) cannot be paired: they raise ValueError."""
    measures: dict[tuple[str, Paired], dict[str, Any]] = {}
    for row in rows:
        cell = (row["task"], row["teacher"], row["scheme"], row["questions"], row["seed"])
        key = (method(row), cell)
        if key in measures:
            raise ValueError(
                f"two rows of {key[0]} for task {cell[0]}, teacher {cell[1]}, scheme {cell[2]}, "
                f"{cell[3]} questions, seed {cell[4]}: a folder holds one row per cell and budget"
            )
        measures[key] = row
    groups: dict[Group, list[tuple[dict[str, Any], dict[str, Any]]]] = defaultdict(list)
    for (name, cell), row in measures.items():
        base = measures.get((baseline, cell))
        if name != baseline and base is not None:
            task, teacher, scheme, questions, _ = cell
            groups[(task, teacher, name, scheme, questions)].append((row, base))
    order = [s.value for s in SchemeName]
    return [
        _effect(group, pairs, baseline)
        for group, pairs in sorted(
            groups.items(), key=lambda item: (*item[0][:3], order.index(item[0][3]), item[0][4])
        )
    ]


def _effect(
    group: Group, pairs: list[tuple[dict[str, Any], dict[str, Any]]], baseline: str
) -> dict[str, Any]:
    """One method against the baseline in one group: each measure's mean difference and
    its interval over seeds (None where a row has no such measure: written before it)."""
    task, teacher, name, scheme, questions = group
    differences: dict[str, list[float] | None] = {}
    for measure in DIFFERENCES:
        values = [(row.get(measure), base.get(measure)) for row, base in pairs]
        known = [(a, b) for a, b in values if a is not None and b is not None]
        differences[measure] = [a - b for a, b in known] if len(known) == len(values) else None
    effect: dict[str, Any] = {
        "task": task,
        "teacher": teacher,
        "method": name,
        "baseline": baseline,
        "scheme": scheme,
        "questions": questions,
        "seeds": len(pairs),
    }
    for measure, found in differences.items():
        low, high = RANGES[measure]
        width = high - low  # a difference lies within minus and plus the range's width
        interval = bounded_interval(found, -width, width) if found else None
        effect[f"{measure}_difference"] = interval
    accuracy, spearman = differences["accuracy"] or [], differences["spearman"] or []
    return {
        **effect,
        "inferred_wrong": _mean_of([row["inferred_wrong"] for row, _ in pairs]),
        "baseline_inferred_wrong": _mean_of([base["inferred_wrong"] for _, base in pairs]),
        "verdict": _verdict(effect["accuracy_difference"], same=not any(accuracy + spearman)),
    }


def _verdict(difference: Interval, same: bool) -> str:
    """On held-out accuracy: an interval that excludes 0 says which way (one seed has
    none); `same`: every seed gave both methods the same measures."""
    _, low, high = difference
    if same:
        return "identical"
    if low is None or high is None:
        return "one seed"
    return "helps" if low > 0 else "hurts" if high < 0 else "no clear difference"


EFFECTS_CAVEAT = (
    "Each verdict is one 95% interval: of many rows, about 1 in 20 reads helps or hurts by "
    "chance alone, and a seed's budgets come from one continuing run, so budgets that agree "
    "are not independent evidence. Trust a pattern across schemes and teachers over one row."
)


def format_effects(effects: list[dict[str, Any]]) -> str:
    """A matrix per task, teacher and budget (schemes by methods), then every row."""
    return _effects_matrices(effects) + "\n## Every comparison\n\n" + _effects_rows(effects)


_MARKS = {"helps": " **helps**", "hurts": " **hurts**"}


def _effects_matrices(effects: list[dict[str, Any]]) -> str:
    """Accuracy differences at a glance: one table per (task, teacher, budget), a row per
    scheme and a column per method, the verdict marked (unmarked: no clear difference)."""
    methods = list(dict.fromkeys(e["method"] for e in effects))
    schemes = [s.value for s in SchemeName if any(e["scheme"] == s.value for e in effects)]
    cells = {
        (e["task"], e["teacher"], e["questions"], e["scheme"], e["method"]): e for e in effects
    }
    blocks = sorted({(e["task"], e["teacher"], e["questions"]) for e in effects})
    baseline = effects[0]["baseline"]
    out = [
        f"# Held-out accuracy against {baseline}, paired by seed: mean difference [95% CI]",
        "\n**helps** / **hurts**: the interval excludes 0; unmarked: no clear difference; "
        "identical: the same measures on every seed; -: not run. Caveat at the end.",
    ]
    for task, teacher, questions in blocks:
        out += [f"\n## {task}, {teacher}, {questions} questions\n"]
        out += ["| scheme | " + " | ".join(methods) + " |", "|---" * (len(methods) + 1) + "|"]
        for scheme in schemes:
            row = [_matrix_cell(cells.get((task, teacher, questions, scheme, m))) for m in methods]
            out.append(f"| {scheme} | " + " | ".join(row) + " |")
    return "\n".join(out) + "\n"


def _matrix_cell(effect: dict[str, Any] | None) -> str:
    if effect is None:
        return "-"
    if effect["verdict"] == "identical":
        return "identical"
    seeds = "" if effect["seeds"] > 1 else " (one seed)"
    return _signed(effect["accuracy_difference"]) + _MARKS.get(effect["verdict"], "") + seeds


def _effects_rows(effects: list[dict[str, Any]]) -> str:
    lines = [
        "| task | teacher | method | scheme | questions | seeds | accuracy difference "
        "[95% CI] | Spearman difference [95% CI] | top-quarter accuracy difference [95% CI] "
        "| top-10% recall difference [95% CI] | regret difference [95% CI] "
        "| wrong inferred (baseline's) | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for e in effects:
        base = e["baseline_inferred_wrong"]
        wrong = "-" if e["inferred_wrong"] is None else f"{e['inferred_wrong']:.3f}"
        wrong += "" if base is None else f" ({base:.3f})"
        lines.append(
            f"| {e['task']} | {e['teacher']} | {e['method']} vs {e['baseline']} | {e['scheme']} "
            f"| {e['questions']} | {e['seeds']} | {_signed(e['accuracy_difference'])} "
            f"| {_signed(e['spearman_difference'])} "
            f"| {_signed(e.get('top_accuracy_difference'))} "
            f"| {_signed(e.get('top_recall_difference'))} | {_signed(e.get('regret_difference'))} "
            f"| {wrong} | {e['verdict']} |"
        )
    return "\n".join(lines) + "\n\n" + EFFECTS_CAVEAT + "\n"


def _signed(value: Interval | None) -> str:
    """A signed difference and its interval (none for one seed, or for seeds that all
    agree); '-' for a measure the rows did not have."""
    if value is None:
        return "-"
    mean, low, high = value
    if low is None or high is None or low == high:
        return _sign(mean)
    return f"{_sign(mean)} [{_sign(low)}, {_sign(high)}]"


def _sign(value: float) -> str:
    return f"{0.0 if abs(value) < 5e-4 else value:+.3f}"  # never "-0.000"
