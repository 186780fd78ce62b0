"""`seqrank watch RUN_DIR`: the saved policy plays N episodes into an mp4 and a contact sheet."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rich.console import Console

from seqrank.cli.options import int_between
from seqrank.errors import UsageError


def add_parser(commands: Any) -> None:
    watch = commands.add_parser(
        "watch",
        help="look at a trained agent: an mp4 and a contact sheet of its episodes",
        description="Play N deterministic episodes with the policy of a run's last checkpoint, "
        "write them as an mp4 (the running true return, and success where the task has one, "
        "as `seqrank report` scores it: Meta-World, block:place, a Gymnasium task whose runs "
        "record a success, under each frame) and a contact sheet PNG, and print each return.",
    )
    watch.add_argument("run", type=Path, help="a run directory (with a checkpoint)")
    watch.add_argument(
        "--episodes", type=int_between(1, 1000), default=2, help="episodes to play (2)"
    )
    watch.add_argument(
        "--size",
        type=int_between(64, 480, "the simulators render at most 480 pixels a side"),
        default=256,
        help="frame size (256)",
    )
    watch.add_argument("--fps", type=int_between(1, 120), default=30, help="video frame rate (30)")
    watch.add_argument("--out", type=Path, help="output folder (default: RUN/watch)")
    watch.set_defaults(handler=run)


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.dirs import check_folder
    from seqrank.training.runs import RunDir
    from seqrank.watch import watch

    folder = args.out or args.run / "watch"
    try:
        RunDir.open(args.run).read_config()
        check_folder(folder, "watch folder")
        episodes, video, sheet = watch(args.run, args.episodes, folder, args.size, args.fps)
    except (ValueError, FileNotFoundError) as problem:
        raise UsageError(str(problem)) from None
    for k, episode in enumerate(episodes, 1):
        success = "" if episode.success is None else f", success {episode.success}"
        out.print(f"episode {k}: return {episode.total:.1f}{success}")
    out.print(f"wrote {video} and {sheet}", highlight=False)
    return 0
