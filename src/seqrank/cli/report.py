"""`seqrank report RUNS_DIR`: tables, statistics and plots over run directories."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rich.console import Console

from seqrank.cli.options import int_between, seed_number
from seqrank.errors import UsageError


def add_parser(commands: Any) -> None:
    report = commands.add_parser(
        "report",
        help="tables (mean ± std, IQM with CIs, probability of improvement) and plots of runs",
        description="Read every run directory under RUNS_DIR and write report.md, report.csv, "
        "report.json and PNG plots of the finished ones (unfinished runs are named and left "
        "out unless --include-unfinished).",
    )
    report.add_argument(
        "runs_dir", type=Path, help="a folder holding run directories (at any depth)"
    )
    report.add_argument("--out", type=Path, help="(default: RUNS_DIR/report)")
    report.add_argument(
        "--bootstrap", type=int_between(100, 1_000_000), default=2000, help="resamples (2000)"
    )
    report.add_argument("--seed", type=seed_number, default=0, help="bootstrap seed (0)")
    report.add_argument("--no-plots", action="store_true", help="write the tables only")
    report.add_argument(
        "--include-unfinished",
        action="store_true",
        help="count runs without summary.json (stopped or still running) with their last "
        "evaluation, marked in the tables",
    )
    report.set_defaults(handler=run)


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.dirs import check_folder
    from seqrank.report.markdown import format_markdown
    from seqrank.report.report import build_report, write_report

    folder = args.out or args.runs_dir / "report"
    try:
        report = build_report(args.runs_dir, args.bootstrap, args.seed, args.include_unfinished)
        check_folder(folder, "report folder")
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    for note in report["notes"]:
        err.print(f"note: {note}", highlight=False, markup=False, soft_wrap=True)
    written = write_report(report, folder, not args.no_plots)
    out.print(format_markdown(report), markup=False, highlight=False)
    err.print("wrote " + ", ".join(str(p) for p in written), highlight=False)
    return 0
