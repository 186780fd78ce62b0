"""`seqrank theory`: expected labelled pairs per session, paper formulas vs exact values."""

from __future__ import annotations

import argparse
import json
from typing import Any

from rich.console import Console

from seqrank import console_tables
from seqrank.cli.options import int_at_least, int_between, probability, seed_number
from seqrank.errors import UsageError
from seqrank.theory import DEFAULT_MS, PAPER_FIGURE13, compute_theory, disagreements

ENUMERATION_LIMIT = 9  # 9! orderings through the real code take about a minute
MAX_M, MAX_SESSIONS = 10_000, 10_000_000


def add_parser(commands: Any) -> None:
    theory = commands.add_parser(
        "theory", help="expected labelled pairs per session: paper formulas vs exact values"
    )
    theory.add_argument(
        "--m",
        nargs="+",
        type=int_between(2, MAX_M),
        default=list(DEFAULT_MS),
        metavar="M",
        help="segments per session (questions = M - 1); default: %(default)s",
    )
    theory.add_argument(
        "--sessions",
        type=int_between(2, MAX_SESSIONS),
        default=2000,
        help="simulated sessions per M and scheme (default: %(default)s)",
    )
    theory.add_argument(
        "--enumerate-max",
        type=int_at_least(0),
        default=8,
        help=f"enumerate all M! orderings for M up to this (at most {ENUMERATION_LIMIT}; "
        "default: %(default)s)",
    )
    theory.add_argument(
        "--delta",
        type=probability,
        default=0.03,
        help="failure probability of the Lemma 3/4 degree bounds (default: %(default)s)",
    )
    theory.add_argument("--seed", type=seed_number, default=0, help="simulation seed (default: 0)")
    theory.add_argument(
        "--format", choices=("table", "json"), default="table", help="printed as (table)"
    )
    theory.set_defaults(handler=run)


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    if args.enumerate_max > ENUMERATION_LIMIT:
        raise UsageError(
            f"--enumerate-max {args.enumerate_max} is too large: enumeration grows as M! "
            f"(accepted: 0 to {ENUMERATION_LIMIT})"
        )
    ms = sorted(set(args.m))
    with console_tables.progress_bar(err) as progress:
        task = progress.add_task("theory", total=len(ms))
        rows = compute_theory(
            ms,
            args.sessions,
            args.enumerate_max,
            args.delta,
            args.seed,
            on_row=lambda m: progress.advance(task),
        )
    findings = disagreements(rows)
    if args.format == "json":
        payload = {
            "parameters": {
                "m": ms,
                "sessions": args.sessions,
                "enumerate_max": args.enumerate_max,
                "delta": args.delta,
                "seed": args.seed,
            },
            "rows": [row.as_dict() for row in rows],
            "disagreements": findings,
            "paper_figure13": PAPER_FIGURE13,
        }
        out.print_json(json.dumps(payload))
        return 0
    console_tables.print_theory(out, rows, findings, args)
    return 0
