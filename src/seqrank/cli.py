"""The `seqrank` command line: train, theory, simulate, label, labels, study-report, sweep,
report, bench."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn

from rich.console import Console

from seqrank import __version__, console_tables
from seqrank.bench.cli import add_bench_parser, run_bench_command
from seqrank.errors import UsageError
from seqrank.feedback.schemes import SCHEMES
from seqrank.feedback.teachers import TEACHER_PRESETS
from seqrank.labelling.cli import add_label_parsers, run_label, run_labels, run_study_report
from seqrank.simulate import simulate
from seqrank.sweeps.cli import add_sweep_parsers, run_report_command, run_sweep_command
from seqrank.theory import DEFAULT_MS, PAPER_FIGURE13, compute_theory, disagreements
from seqrank.train_cli import add_train_parser, run_train

ENUMERATION_LIMIT = 9  # 9! orderings through the real code take about a minute


class _Parser(argparse.ArgumentParser):
    """Bad input: one line naming the problem, exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _int_at_least(minimum: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{value} is too small; it must be >= {minimum}")
        return value

    return parse


def _probability(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"{value} must lie strictly between 0 and 1")
    return value


def _names(accepted: Sequence[str], what: str) -> Callable[[str], list[str]]:
    def parse(text: str) -> list[str]:
        names = [n.strip() for n in text.split(",") if n.strip()]
        unknown = [n for n in names if n not in accepted]
        if unknown or not names:
            bad = ", ".join(repr(n) for n in unknown) or repr(text)
            raise argparse.ArgumentTypeError(
                f"unknown {what} {bad}; accepted: {', '.join(accepted)} (comma-separated)"
            )
        return list(dict.fromkeys(names))

    return parse


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="seqrank", description=__doc__)
    parser.add_argument("--version", action="version", version=f"seqrank {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    theory = commands.add_parser(
        "theory", help="expected labelled pairs per session: paper formulas vs exact values"
    )
    theory.add_argument(
        "--m",
        nargs="+",
        type=_int_at_least(2),
        default=list(DEFAULT_MS),
        metavar="M",
        help="segments per session (questions = M - 1); default: %(default)s",
    )
    theory.add_argument(
        "--sessions",
        type=_int_at_least(2),
        default=2000,
        help="simulated sessions per M and scheme (default: %(default)s)",
    )
    theory.add_argument(
        "--enumerate-max",
        type=_int_at_least(0),
        default=8,
        help=f"enumerate all M! orderings for M up to this (at most {ENUMERATION_LIMIT}; "
        "default: %(default)s)",
    )
    theory.add_argument(
        "--delta",
        type=_probability,
        default=0.03,
        help="failure probability of the Lemma 3/4 degree bounds (default: %(default)s)",
    )
    theory.add_argument("--seed", type=int, default=0, help="simulation seed (default: 0)")
    theory.add_argument("--format", choices=("table", "json"), default="table")
    theory.set_defaults(handler=_run_theory)

    sim = commands.add_parser(
        "simulate", help="feedback efficiency of every scheme under every teacher preset"
    )
    sim.add_argument(
        "--questions",
        type=_int_at_least(1),
        default=50,
        help="questions per session, N (default: %(default)s)",
    )
    sim.add_argument(
        "--sessions",
        type=_int_at_least(2),
        default=200,
        help="sessions per scheme and teacher (default: %(default)s)",
    )
    sim.add_argument(
        "--schemes",
        type=_names(list(SCHEMES), "scheme"),
        default=list(SCHEMES),
        help=f"comma-separated, from: {', '.join(SCHEMES)} (default: all)",
    )
    sim.add_argument(
        "--teachers",
        type=_names(list(TEACHER_PRESETS), "teacher preset"),
        default=list(TEACHER_PRESETS),
        help=f"comma-separated, from: {', '.join(TEACHER_PRESETS)} (default: all)",
    )
    sim.add_argument("--seed", type=int, default=0, help="seed (default: 0)")
    sim.add_argument(
        "--out",
        type=Path,
        default=Path("seqrank-out/simulate"),
        help="folder for simulate.json and simulate.png (default: %(default)s)",
    )
    sim.add_argument("--no-plot", action="store_true", help="skip the PNG plot")
    sim.add_argument(
        "--format",
        choices=("table", "json"),
        default="table",
        help="what to print on stdout (the JSON file is written either way)",
    )
    sim.set_defaults(handler=_run_simulate)

    add_train_parser(commands)
    commands.choices["train"].set_defaults(handler=run_train)
    add_label_parsers(commands, _Parser)
    commands.choices["label"].set_defaults(handler=run_label)
    commands.choices["labels"].set_defaults(handler=run_labels)
    commands.choices["study-report"].set_defaults(handler=run_study_report)
    add_sweep_parsers(commands)
    commands.choices["sweep"].set_defaults(handler=run_sweep_command)
    commands.choices["report"].set_defaults(handler=run_report_command)
    add_bench_parser(commands)
    commands.choices["bench"].set_defaults(handler=run_bench_command)
    return parser


def _run_theory(args: argparse.Namespace, out: Console, err: Console) -> int:
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


def _run_simulate(args: argparse.Namespace, out: Console, err: Console) -> int:
    with console_tables.progress_bar(err) as progress:
        task = progress.add_task("simulate", total=len(args.schemes) * len(args.teachers))
        results = simulate(
            args.schemes,
            args.teachers,
            args.questions,
            args.sessions,
            args.seed,
            on_cell=lambda cell: progress.advance(task),
        )
    args.out.mkdir(parents=True, exist_ok=True)
    payload = {
        "parameters": {
            "questions": args.questions,
            "sessions": args.sessions,
            "schemes": args.schemes,
            "teachers": args.teachers,
            "seed": args.seed,
        },
        "results": [cell.as_dict() for cell in results],
    }
    json_path = args.out / "simulate.json"
    json_path.write_text(json.dumps(payload, indent=2) + "\n")
    png_path = None
    if not args.no_plot:
        from seqrank.plots import plot_simulation  # matplotlib is slow to import

        png_path = args.out / "simulate.png"
        plot_simulation(results, png_path)
    if args.format == "json":
        out.print_json(json.dumps(payload))
    else:
        console_tables.print_simulation(out, results)
        err.print(f"wrote {json_path}" + (f" and {png_path}" if png_path else ""))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
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
