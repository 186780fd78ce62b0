"""Each scheme against pairwise questions on a reward-benchmark grid, paired by seed.

Issue 46, item 2: `seqrank reward-bench report` sets each control against its scheme's
default (effects.md); this sets sequential and root against pairwise in the same
order and cell, seed by seed, on every measure, per question (the same budget) and per
clip watched (a pairwise question shows two new clips, a sequential or root question one:
a scheme's 2q questions against pairwise's q, where the grid has both budgets). Each
difference is a mean with its 95% interval over seeds (`bounded_interval`, as effects.md).

    python scripts/schemes_vs_pairwise.py GRID_FOLDER [--budgets 100,500,1000]
        [--against-order uniform]   (every order's schemes against pairwise in one order)
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
    base_order: str | None = None,
) -> str:
    """`cell`'s measure minus pairwise's at `base_questions` (in `base_order`, by default
    the cell's), paired by seed ('-' if none)."""
    base = (cell[0], base_order or cell[1], "pairwise", base_questions)
    if base == cell:
        return "-"
    seeds = sorted(k[4] for k in rows if k[:4] == cell)
    pairs = [
        (rows[(*cell, s)][measure], rows[(*base, s)][measure]) for s in seeds if (*base, s) in rows
    ]
    if not pairs:
        return "-"
    low, high = RANGES[measure]
    mean, lower, upper = bounded_interval([a - b for a, b in pairs], low - high, high - low)
    if lower is None or upper is None:
        return f"{mean:+.3f}"
    return f"{mean:+.3f} [{lower:+.3f}, {upper:+.3f}]"


def per_question(
    rows: dict[Key, dict[str, Any]], budgets: list[int], base_order: str | None = None
) -> list[str]:
    against = f" against pairwise in {base_order} order" if base_order else ""
    lines = [f"## Per question (the same budget){against}", ""]
    for task, order in sorted({(k[0], k[1]) for k in rows}):
        named = (("pairwise",) if base_order and order != base_order else ()) + SCHEMES
        schemes = [s for s in named if any(k[:3] == (task, order, s) for k in rows)]
        lines += [f"### {task}, {order} order", ""]
        lines += ["| measure | scheme | " + " | ".join(f"{q} questions" for q in budgets) + " |"]
        lines += ["|---|---|" + "---|" * len(budgets)]
        for measure in DIFFERENCES:
            for scheme in schemes:
                cell = (task, order, scheme)
                cells = [difference(rows, (*cell, q), q, measure, base_order) for q in budgets]
                lines += [f"| {LABELS[measure]} | {scheme} | " + " | ".join(cells) + " |"]
        lines += [""]
    return lines


def per_clip(rows: dict[Key, dict[str, Any]], base_order: str | None = None) -> list[str]:
    against = f" in {base_order} order" if base_order else ""
    lines = [f"## Per clip watched (a scheme's 2q questions against pairwise's q{against})", ""]
    lines += ["| task | order | scheme | questions | pairwise's | accuracy difference |"]
    lines += ["|---|---|---|---|---|---|"]
    budgets = sorted({k[3] for k in rows})
    for task, order in sorted({(k[0], k[1]) for k in rows}):
        for scheme in ("sequential", "root"):
            for q in budgets:
                if 2 * q in budgets and any(k[:4] == (task, order, scheme, 2 * q) for k in rows):
                    cell = (task, order, scheme, 2 * q)
                    found = difference(rows, cell, q, "accuracy", base_order)
                    lines += [f"| {task} | {order} | {scheme} | {2 * q} | {q} | {found} |"]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("grid", type=Path, help="a reward-bench folder with rows.jsonl")
    parser.add_argument("--budgets", default="100,500,1000", help="(100,500,1000)")
    parser.add_argument(
        "--against-order",
        help="compare every order's schemes with pairwise in this order (default: the same)",
    )
    args = parser.parse_args()
    rows = read_rows(args.grid)
    budgets = [int(b) for b in args.budgets.split(",")]
    orders = sorted({k[1] for k in rows})
    if args.against_order and args.against_order not in orders:
        parser.error(f"--against-order {args.against_order!r}: the grid has {', '.join(orders)}")
    title = f"# Schemes against pairwise questions, paired by seed: {args.grid}"
    lines = [title, "", "Mean difference [95% interval over seeds]; `-`: not in the grid.", ""]
    settings = json.loads((args.grid / "settings.json").read_text())
    if settings.get("window_steps"):  # each budget is scored on another window's segments
        clips = ["## Per clip watched", "", "Not compared: in a grid of windows a scheme's 2q "
                 "questions and pairwise's q are scored on different windows."]  # fmt: skip
    else:
        clips = per_clip(rows, args.against_order)
    print("\n".join(lines + per_question(rows, budgets, args.against_order) + clips))


if __name__ == "__main__":
    main()
