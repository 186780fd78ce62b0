"""Each scheme against pairwise questions on a reward-benchmark grid, paired by seed.

Issue 46, item 2: `seqrank reward-bench report` sets each control against its scheme's
default (effects.md); this sets sequential and root against pairwise in the same
order and cell, seed by seed, on every measure, per question (the same budget) and per
clip watched (a pairwise question shows two new clips, a sequential or root question one:
a scheme's 2q questions against pairwise's q, where the grid has both budgets). Each
difference is a mean with its 95% interval over seeds (`bounded_interval`, as effects.md).

    python scripts/schemes_vs_pairwise.py GRID_FOLDER [--budgets 100,500,1000]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from seqrank.rewardbench.intervals import bounded_interval
from seqrank.rewardbench.summary import DIFFERENCES, RANGES

SCHEMES = ("sequential", "root", "ranked")
LABELS = {
    "accuracy": "accuracy",
    "spearman": "Spearman",
    "top_accuracy": "top-quarter accuracy",
    "top_recall": "top-10% recall",
    "regret": "regret, best of 10 (lower is better)",
}
Key = tuple[str, str, str, int, int]  # task, order, scheme, questions, seed


def read_rows(folder: Path) -> dict[Key, dict[str, Any]]:
    """The grid's oracle rows with the default learner, keyed by cell and seed."""
    rows: dict[Key, dict[str, Any]] = {}
    for line in (folder / "rows.jsonl").read_text().splitlines():
        row = json.loads(line)
        if row.get("stop", "all") != "all" or row.get("augment", "full") != "full":
            continue  # a fitting control: compared within its scheme by effects.md
        key = (
            row["task"],
            row.get("order", "uniform"),
            row["scheme"],
            row["questions"],
            row["seed"],
        )
        rows[key] = row
    return rows


def difference(
    rows: dict[Key, dict[str, Any]],
    cell: tuple[str, str, str, int],
    base_questions: int,
    measure: str,
) -> str:
    """`cell`'s measure minus pairwise's at `base_questions`, paired by seed ('-' if none)."""
    task, order = cell[0], cell[1]
    seeds = sorted(k[4] for k in rows if k[:4] == cell)
    pairs = [
        (rows[(*cell, s)][measure], rows[(task, order, "pairwise", base_questions, s)][measure])
        for s in seeds
        if (task, order, "pairwise", base_questions, s) in rows
    ]
    if not pairs:
        return "-"
    low, high = RANGES[measure]
    mean, lower, upper = bounded_interval([a - b for a, b in pairs], low - high, high - low)
    if lower is None or upper is None:
        return f"{mean:+.3f}"
    return f"{mean:+.3f} [{lower:+.3f}, {upper:+.3f}]"


def per_question(rows: dict[Key, dict[str, Any]], budgets: list[int]) -> list[str]:
    lines = ["## Per question (the same budget)", ""]
    for task, order in sorted({(k[0], k[1]) for k in rows}):
        schemes = [s for s in SCHEMES if any(k[:3] == (task, order, s) for k in rows)]
        lines += [f"### {task}, {order} order", ""]
        lines += ["| measure | scheme | " + " | ".join(f"{q} questions" for q in budgets) + " |"]
        lines += ["|---|---|" + "---|" * len(budgets)]
        for measure in DIFFERENCES:
            for scheme in schemes:
                cells = [difference(rows, (task, order, scheme, q), q, measure) for q in budgets]
                lines += [f"| {LABELS[measure]} | {scheme} | " + " | ".join(cells) + " |"]
        lines += [""]
    return lines


def per_clip(rows: dict[Key, dict[str, Any]]) -> list[str]:
    lines = ["## Per clip watched (a scheme's 2q questions against pairwise's q)", ""]
    lines += ["| task | order | scheme | questions | pairwise's | accuracy difference |"]
    lines += ["|---|---|---|---|---|---|"]
    budgets = sorted({k[3] for k in rows})
    for task, order in sorted({(k[0], k[1]) for k in rows}):
        for scheme in ("sequential", "root"):
            for q in budgets:
                if 2 * q in budgets and any(k[:4] == (task, order, scheme, 2 * q) for k in rows):
                    found = difference(rows, (task, order, scheme, 2 * q), q, "accuracy")
                    lines += [f"| {task} | {order} | {scheme} | {2 * q} | {q} | {found} |"]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("grid", type=Path, help="a reward-bench folder with rows.jsonl")
    parser.add_argument("--budgets", default="100,500,1000", help="(100,500,1000)")
    args = parser.parse_args()
    rows = read_rows(args.grid)
    budgets = [int(b) for b in args.budgets.split(",")]
    title = f"# Schemes against pairwise questions, paired by seed: {args.grid}"
    lines = [title, "", "Mean difference [95% interval over seeds]; `-`: not in the grid.", ""]
    settings = json.loads((args.grid / "settings.json").read_text())
    if settings.get("window_steps"):  # each budget is scored on another window's segments
        clips = ["## Per clip watched", "", "Not compared: in a grid of windows a scheme's 2q "
                 "questions and pairwise's q are scored on different windows."]  # fmt: skip
    else:
        clips = per_clip(rows)
    print("\n".join(lines + per_question(rows, budgets) + clips))


if __name__ == "__main__":
    main()
