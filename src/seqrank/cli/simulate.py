"""`seqrank simulate`: feedback efficiency of every scheme under every teacher preset."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

from rich.console import Console

from seqrank import console_tables
from seqrank.cli.option_help import MEANINGS
from seqrank.cli.options import int_between, names, number_between, seed_number
from seqrank.cli.reward_bench import teacher_list
from seqrank.errors import UsageError
from seqrank.feedback.checking import Recheck
from seqrank.feedback.schemes import SCHEMES
from seqrank.feedback.teachers import (
    CROWD_PREFIX,
    TEACHER_PRESETS,
    parse_teacher,
    scripted_config,
)
from seqrank.simulate import AUGMENTS, CrowdSettings, simulate

# Recheck fields that a run's loop sets, not the user: left out of the printed settings
_RUN_STATE = ("contradicted", "model_returns")


def add_parser(commands: Any) -> None:
    sim = commands.add_parser(
        "simulate", help="feedback efficiency of every scheme under every teacher preset"
    )
    sim.add_argument(
        "--questions",
        type=int_between(1, 10_000),
        default=50,
        help="questions per session, N (default: %(default)s)",
    )
    sim.add_argument(
        "--sessions",
        type=int_between(2, 1_000_000),
        default=200,
        help="sessions per scheme and teacher (default: %(default)s)",
    )
    sim.add_argument(
        "--schemes",
        type=names(list(SCHEMES), "scheme"),
        default=list(SCHEMES),
        help=f"comma-separated, from: {', '.join(SCHEMES)} (default: all)",
    )
    sim.add_argument(
        "--teachers",
        type=teacher_list,
        default=list(TEACHER_PRESETS),
        help=f"scripted teachers, as --teacher of `seqrank train` takes one: presets "
        f"({', '.join(TEACHER_PRESETS)}), each optionally followed by its knobs, "
        "comma-separated: a knob=value part belongs to the teacher before it, e.g. "
        "oracle,mistake,eps_mistake=0.2; ';' also separates teachers, e.g. "
        "'oracle;beta=1'; or a simulated crowd, crowd:oracle+mistake+noisy, whose "
        "members' estimated reliability (as a run estimates it) is printed (default: every preset)",
    )
    sim.add_argument(
        "--augment",
        type=names(list(AUGMENTS), "augmentation"),
        default=["full"],
        help="comma-separated, from: full (the paper's closure), checked (noise-aware: "
        "re-checks and fewer unrepeated answers per inferred pair) (default: full)",
    )
    _add_checking(sim)
    _add_crowd(sim)
    sim.add_argument("--seed", type=seed_number, default=0, help="seed (default: 0)")
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
    sim.set_defaults(handler=run)


def _add_crowd(sim: argparse.ArgumentParser) -> None:
    """A crowd teacher's evidence settings, as `seqrank train` takes them, with its
    defaults and its help."""
    defaults = CrowdSettings()
    for flag, parse, default, metavar in (
        ("--overlap", number_between(0.0, 1.0), defaults.overlap, "SHARE"),
        ("--overlap-until", int_between(0, 10_000), defaults.overlap_until, "N"),
        ("--closure-checks", int_between(0, 1), int(defaults.closure_checks), "0|1"),
    ):
        meaning = MEANINGS[flag.removeprefix("--").replace("-", "_")]
        sim.add_argument(
            flag,
            type=parse,
            default=default,
            metavar=metavar,
            help=f"{meaning} (default: %(default)s)",
        )


def _add_checking(sim: argparse.ArgumentParser) -> None:
    """`--augment checked`'s settings, with `seqrank train`'s defaults."""
    checking = Recheck()
    for flag, default, meaning in (
        ("--recheck-gain", checking.gain, "re-ask an answer that would imply this many new pairs"),
        ("--recheck-twice-gain", checking.twice_gain, "... twice from N on, once contradicted"),
        ("--path-unchecked", checking.path_unchecked, "unrepeated answers on an inferred path"),
    ):
        sim.add_argument(
            flag,
            type=int_between(0, 1_000_000),
            default=default,
            help=f"with --augment checked: {meaning} (default: %(default)s)",
        )


def _crowd_settings(args: argparse.Namespace) -> CrowdSettings:
    """The crowd's settings; UsageError when one is set off its default and no teacher is
    a crowd (it would change nothing), as `seqrank train` refuses them for one teacher."""
    crowd = CrowdSettings(args.overlap, args.overlap_until, bool(args.closure_checks))
    changed = [
        f"--{f.name.replace('_', '-')} {getattr(args, f.name)}"
        for f in fields(crowd)
        if getattr(crowd, f.name) != f.default
    ]
    if changed and not any(t.startswith(CROWD_PREFIX) for t in args.teachers):
        many = len(changed) > 1
        raise UsageError(
            f"{' and '.join(changed)} {'act' if many else 'acts'} on a crowd's answers; "
            f"--teachers names no crowd ({', '.join(map(repr, args.teachers))}): leave "
            f"{'them' if many else 'it'} out, or add one (crowd:oracle+mistake+noisy)"
        )
    return crowd


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.dirs import check_folder

    try:
        check_folder(args.out, "--out")
        checking = Recheck(args.recheck_gain, args.recheck_twice_gain, args.path_unchecked)
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    crowd = _crowd_settings(args)
    for teacher in args.teachers:  # each checked before anything runs
        try:
            if not teacher.startswith(CROWD_PREFIX):
                scripted_config(teacher)
            parse_teacher(teacher)
        except ValueError as problem:
            raise UsageError(f"--teachers {teacher!r}: {problem}") from None
    with console_tables.progress_bar(err) as progress:
        cells = len(args.schemes) * len(args.teachers) * len(args.augment)
        task = progress.add_task("simulate", total=cells)
        results = simulate(
            args.schemes,
            args.teachers,
            args.questions,
            args.sessions,
            args.seed,
            on_cell=lambda cell: progress.advance(task),
            augments=args.augment,
            checking=checking,
            crowd_settings=crowd,
        )
    args.out.mkdir(parents=True, exist_ok=True)
    payload = {
        "parameters": {
            "questions": args.questions,
            "sessions": args.sessions,
            "schemes": args.schemes,
            "teachers": args.teachers,
            "augment": args.augment,
            "overlap": crowd.overlap,
            "overlap_until": crowd.overlap_until,
            "closure_checks": int(crowd.closure_checks),
            "recheck": {k: v for k, v in asdict(checking).items() if k not in _RUN_STATE},
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
