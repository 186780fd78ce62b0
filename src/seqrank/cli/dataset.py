"""`seqrank dataset make|info`: offline datasets in Minari's format, made here (a run's
episodes, Meta-World's scripted policies, random play, mixtures) and described."""

from __future__ import annotations

import argparse
import json
import shlex
from typing import Any

from rich.console import Console

from seqrank.cli.options import Parser, int_between, seed_number
from seqrank.errors import UsageError

NAME_HELP = (
    "a Minari dataset id, (namespace/)name-vN, in Minari's local datasets folder "
    "($MINARI_DATASETS_PATH, else ~/.minari/datasets), or a dataset folder's path (one "
    "that begins with /, . or ~, or is not an id)"
)


def add_parser(commands: Any) -> None:
    dataset = commands.add_parser(
        "dataset",
        help="make or describe an offline dataset (Minari's format)",
        description="Offline datasets in Minari's format, written locally (nothing is "
        "downloaded): a seqrank run's kept episodes (medium-replay), Meta-World's scripted "
        "policies with Gaussian action noise, uniform random play, or a mixture of them, "
        "played through seqrank's own environments.",
    )
    actions = dataset.add_subparsers(dest="action", required=True, parser_class=Parser)
    _add_make(actions)
    info = actions.add_parser("info", help="episodes, returns, success rate and provenance")
    info.add_argument("dataset", help=NAME_HELP)
    info.add_argument(
        "--task", help="the task of a dataset that does not name one (one made elsewhere)"
    )
    info.add_argument("--json", action="store_true", help="print the description as JSON")
    info.set_defaults(handler=run_info)


def _add_make(actions: Any) -> None:
    make = actions.add_parser("make", help="write a new Minari dataset from its sources")
    make.add_argument("--task", required=True, help="the task, as `seqrank train` takes it")
    make.add_argument(
        "--source",
        action="append",
        required=True,
        help="where episodes come from: random, scripted (Meta-World's scripted policy "
        "with --noise), scripted:SIGMA (its own noise) or run:PATH (a run's kept "
        "episodes), each optionally =SHARE of --episodes; repeatable, e.g. --source "
        "scripted=0.7 --source random (sources without a share split what the shares "
        "leave equally; shares sum to 1 at most, and to 1 where every source has one)",
    )
    make.add_argument(
        "--episodes",
        type=int_between(1, 1_000_000),
        help="episodes in all, shared between the sources; needed unless the one source "
        "is a run (then all its kept episodes)",
    )
    make.add_argument(
        "--noise",
        type=float,
        default=0.1,
        help="the standard deviation of the Gaussian noise added to scripted actions, which "
        "lie in [-1, 1] (0.1)",
    )
    make.add_argument("--seed", type=seed_number, default=0, help="(0)")
    make.add_argument("--out", required=True, help=f"the new dataset: {NAME_HELP}")
    make.set_defaults(handler=run_make)


def run_make(args: argparse.Namespace, out: Console, err: Console) -> int:
    """The input is checked before anything is played or written; a failure while
    writing leaves nothing behind (`save_episodes`). Ctrl-C or SIGTERM stop it at once
    (there is nothing to save): one line, and 130 or 143 as the other commands exit."""
    from seqrank.offline.make import MakeRequest, check_out, check_request, make_dataset
    from seqrank.offline.sources import parse_source
    from seqrank.training.stopping import interrupt_on_signals

    try:
        sources = [parse_source(text) for text in args.source]
        command = "seqrank " + shlex.join(args.command_line)
        request = MakeRequest(args.task, sources, args.episodes, args.noise, args.seed, command)
        check_out(args.out)
        check_request(request)
    except (ValueError, FileNotFoundError) as problem:
        raise UsageError(str(problem)) from None
    with interrupt_on_signals(lambda: None) as stop:
        try:
            location = make_dataset(request, args.out)
        except KeyboardInterrupt:
            err.print(f"interrupted: nothing written (no dataset {args.out})",
                      highlight=False, markup=False, soft_wrap=True)  # fmt: skip
            return stop.exit_code()
        except ValueError as problem:  # SettingError too; save_episodes removed what it wrote
            raise UsageError(str(problem)) from None
    out.print(f"dataset {location.dataset_id} written to {location.folder}", highlight=False)
    _print_info(_describe(args.out), out)
    return 0


def run_info(args: argparse.Namespace, out: Console, err: Console) -> int:
    info = _describe(args.dataset, args.task)
    if args.json:
        out.print_json(json.dumps(info))
    else:
        _print_info(info, out)
    return 0


def _describe(name: str, task: str | None = None) -> dict[str, Any]:
    from seqrank.offline.make import describe

    try:
        return describe(name, task)
    except ValueError as problem:
        raise UsageError(str(problem)) from None


def _print_info(info: dict[str, Any], out: Console) -> None:
    ret, length = info["return"], info["episode_length"]
    lines = [
        f"dataset      {info['dataset']} ({info['path']})",
        f"task         {info['task']} (observations {info['obs_dim']}, actions {info['act_dim']})",
        f"episodes     {info['episodes']} ({info['transitions']} transitions, "
        f"{length['min']}-{length['max']} steps each)",
        f"return       mean {ret['mean']:.2f}, sd {ret['std']:.2f}, "
        f"min {ret['min']:.2f}, max {ret['max']:.2f}",
    ]
    if info["success_rate"] is not None:
        lines.append(f"success      {100 * info['success_rate']:.1f}% of episodes")
    provenance = info["provenance"]
    if provenance:
        for part in provenance.get("sources", []):
            lines.append(f"source       {_part_line(part)}")
        lines.append(f"seed         {provenance.get('seed')}")
        lines.append(f"made by      seqrank {provenance.get('seqrank_version')}: "
                     f"{provenance.get('command')}")  # fmt: skip
    else:
        lines.append("provenance   not made by seqrank (no seqrank entry in its metadata)")
    for line in lines:
        out.print(line, highlight=False, markup=False)


def _part_line(part: dict[str, Any]) -> str:
    what = part["source"]
    if what == "scripted":
        what = f"scripted (noise {part['noise']:g})"
    elif what == "run":
        what = f"run {part['run']}"
    return f"{part['episodes']} episodes, {part['transitions']} transitions: {what}"
