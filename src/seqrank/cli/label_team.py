"""`seqrank label`'s options for a team: its names, the overlap, gold pairs."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from seqrank.cli.options import int_between, number_between
from seqrank.feedback.overlap import EVIDENCE_UNTIL, OVERLAP


def add_team(parser: argparse.ArgumentParser) -> None:
    """`label offline`'s team: its names and how much of its answers is asked again."""
    parser.add_argument(
        "--annotators",
        default="",
        metavar="NAMES",
        help="a team sharing the sessions out, comma-separated (alice,bob): each gets an "
        "address of their own, the operator a page of their own (/operator); names of ASCII "
        "letters, digits, '-', '_' and '.', starting with a letter, 'operator' reserved",
    )
    parser.add_argument(
        "--overlap",
        type=number_between(0.0, 1.0),
        default=OVERLAP,
        help="with --annotators: the share of answers also asked of a second annotator (0.1)",
    )
    parser.add_argument(
        "--overlap-until",
        type=int_between(0, 10_000),
        default=EVIDENCE_UNTIL,
        metavar="N",
        help="with --annotators: every answer of a member with fewer than N answers shared "
        "with somebody else is also asked of two others; 0: the share --overlap only "
        f"({EVIDENCE_UNTIL})",
    )


def add_gold(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--gold",
        type=Path,
        metavar="FILE",
        help="with --annotators: a label file of the task whose answers you trust (e.g. "
        "yours, from label offline); its pairs are shown to each member now and then among "
        "their questions, unannounced, and count against whoever contradicts them",
    )


def gold_for(args: argparse.Namespace, task: str, length: int, team: Any) -> Any:
    """The gold pairs `--gold` names, checked against the run (None without it)."""
    if args.gold is None:
        return None
    if not team:
        raise ValueError(
            f"--gold {args.gold} acts on a team's answers; one person answers here: leave it "
            "out, or name a team with --annotators"
        )
    from seqrank.labelling.gold import read_gold

    return read_gold(args.gold, task, length)
