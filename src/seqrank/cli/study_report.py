"""`seqrank study-report`: satisfaction and reward per method over a study's participants."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from rich.console import Console

from seqrank.errors import UsageError


def add_parser(commands: Any) -> None:
    report = commands.add_parser(
        "study-report",
        help="satisfaction and reward per method over a study's participants, paired t-tests",
    )
    report.add_argument("study_dir", type=Path, help="the --study-dir of `seqrank label study`")
    report.add_argument("--json", type=Path, help="also write the numbers as JSON here")
    report.set_defaults(handler=run)


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.dirs import check_file
    from seqrank.labelling.study import format_report, study_report

    try:
        report = study_report(args.study_dir)
        if args.json is not None:
            check_file(args.json, "--json")
        check_file(args.study_dir / "study-report.md", "study report")
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    text = format_report(report)
    out.print(text, highlight=False, markup=False)
    (args.study_dir / "study-report.md").write_text(text)
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))
    return 0
