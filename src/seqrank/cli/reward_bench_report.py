"""`seqrank reward-bench report`: a grid folder's table, curves and paired effects, written
from its rows (also what `reward-bench run` writes when its grid is done)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from rich.console import Console

from seqrank.errors import UsageError


def add_report(actions: Any) -> None:
    report = actions.add_parser(
        "report",
        help="a grid folder's table, curves and paired effects, from its rows (nothing runs)",
    )
    report.add_argument("folder", type=Path, help="a grid's folder (`run --out`: its rows.jsonl)")
    report.add_argument(
        "--baseline",
        default="plain",
        help="the method every other is compared with, seed by seed, in effects.md (plain)",
    )
    report.set_defaults(handler=run_report)


def run_report(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.rewardbench.summary import method
    from seqrank.rows import read_rows

    rows = read_rows(args.folder / "rows.jsonl")
    if not rows:
        raise UsageError(f"no rows in {args.folder}: give a folder that `reward-bench run` wrote")
    methods = sorted({method(row) for row in rows})
    if args.baseline not in methods:
        raise UsageError(
            f"--baseline {args.baseline!r} has no rows in {args.folder}; "
            f"accepted: {', '.join(methods)}"
        )
    try:
        write_report(rows, args.folder, args.baseline, out)
    except ValueError as problem:  # two rows of one cell: they cannot be paired
        raise UsageError(f"{args.folder}: {problem}") from None
    return 0


def write_report(rows: list[dict[str, Any]], folder: Path, baseline: str, out: Console) -> None:
    """table.md, summary.json and the curves (against questions asked, and clips watched and
    annotator seconds where the rows counted them); with other methods beside the baseline, also
    effects.md and effects.json (each against the baseline, seed by seed)."""
    from seqrank.rewardbench.cells import distinct_rows
    from seqrank.rewardbench.curves import curve_paths, plot_task
    from seqrank.rewardbench.summary import format_effects, format_table, paired_effects, summarise

    rows = distinct_rows(rows)
    summary = summarise(rows)
    table = format_table(summary)
    (folder / "table.md").write_text(table)
    (folder / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    for task in sorted({e["task"] for e in summary}):  # against questions, clips, seconds
        for cost, path in curve_paths(summary, task, folder).items():
            plot_task(summary, task, path, cost)
    out.print(table, highlight=False, markup=False)
    effects = paired_effects(rows, baseline)
    for name in ("effects.md", "effects.json"):  # none stale from rows of another time
        (folder / name).unlink(missing_ok=True)
    if effects:
        (folder / "effects.md").write_text(format_effects(effects))
        (folder / "effects.json").write_text(json.dumps(effects, indent=1) + "\n")
        message = f"each method against {baseline}, seed by seed: {folder / 'effects.md'}"
    else:
        message = f"no other method shares a cell with {baseline}: no effects.md"
    out.print(message, highlight=False)
    out.print(f"rows, table and curves in {folder}", highlight=False)
