"""The `seqrank` command line: train, theory, simulate, label, labels, study-report, sweep,
report, bench, reward-bench, dataset, offline, watch."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from rich.console import Console

import seqrank.cli.bench as bench
import seqrank.cli.dataset as dataset
import seqrank.cli.label as label
import seqrank.cli.labels as labels
import seqrank.cli.offline as offline
import seqrank.cli.report as report
import seqrank.cli.reward_bench as reward_bench
import seqrank.cli.simulate as simulate
import seqrank.cli.study_report as study_report
import seqrank.cli.sweep as sweep
import seqrank.cli.theory as theory
import seqrank.cli.train as train
import seqrank.cli.watch as watch
from seqrank import __version__
from seqrank.cli.options import Parser
from seqrank.errors import UsageError

# Each module adds its sub-command's parser, whose `handler` default runs it; in help order.
SUBCOMMANDS = (
    theory,
    simulate,
    train,
    label,
    labels,
    study_report,
    sweep,
    report,
    bench,
    reward_bench,
    dataset,
    offline,
    watch,
)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="seqrank", description=__doc__)
    parser.add_argument("--version", action="version", version=f"seqrank {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in SUBCOMMANDS:
        module.add_parser(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # bad options (2), --help or --version (0): a code, no raise
        return stop.code if isinstance(stop.code, int) else 0
    args.command_line = list(sys.argv[1:] if argv is None else argv)
    # Piped output (files, CI logs) gets room for the wide tables instead of rich's 80.
    out = Console(soft_wrap=False, width=None if sys.stdout.isatty() else 150)
    err = Console(stderr=True)
    try:
        code: int = args.handler(args, out, err)
    except UsageError as problem:
        print(f"seqrank {args.command}: error: {problem}", file=sys.stderr)
        return 2
    return code
