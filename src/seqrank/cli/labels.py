"""`seqrank labels export|import`: a labelling directory's answers as JSONL."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rich.console import Console

from seqrank.cli.options import Parser, int_between
from seqrank.errors import UsageError


def add_parser(commands: Any) -> None:
    labels = commands.add_parser("labels", help="export or import labels as JSONL")
    actions = labels.add_subparsers(dest="action", required=True, parser_class=Parser)
    export = actions.add_parser(
        "export",
        help="write the answers of a labelling or run directory as JSONL",
    )
    export.add_argument(
        "directory", type=Path, help="a labelling directory (labels.sqlite) or a run directory"
    )
    export.add_argument(
        "-o", "--output", type=Path, required=True, help="the new JSONL file; not one already there"
    )
    export.add_argument(
        "--agreed-by",
        type=int_between(2, 1000),
        default=None,
        metavar="N",
        help="only the pairs N or more people of a team answered alike, every answer strict "
        "(a gold file for the team's next run: `label online --gold`); off: every answer",
    )
    load = actions.add_parser(
        "import",
        help="add a JSONL file's answers to a labelling directory: all of them in one "
        "transaction, or none when any record cannot be stored",
    )
    load.add_argument("file", type=Path, help="a JSONL file from `seqrank labels export`")
    load.add_argument("directory", type=Path, help="the labelling directory to add them to")
    labels.set_defaults(handler=run)


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    try:
        if args.action == "export":
            count, source = _export(args.directory, args.output, args.agreed_by)
            out.print(f"{count} answers of {source} written to {args.output}", highlight=False)
            if args.agreed_by is not None and not _all_keep_states(args.output):
                out.print(
                    "its segments keep no physics states (a task without MuJoCo state), so "
                    "it cannot serve as --gold: the page could not show their clips",
                    highlight=False,
                )
        else:
            count, db_path = _import(args.file, args.directory)
            out.print(f"{count} answers added to {db_path}", highlight=False)
    except (ValueError, FileNotFoundError) as problem:
        raise UsageError(str(problem)) from None
    return 0


def _export(directory: Path, output: Path, agreed_by: int | None) -> tuple[int, str]:
    """A labelling database's answers, or a run's from its checkpoint (scripted and
    replayed teachers, which have no database); `agreed_by`: a team's agreed pairs only."""
    from seqrank.dirs import check_file
    from seqrank.labelling.db import DB_NAME, LabelDB
    from seqrank.labelling.jsonl import export_file

    check_file(output, "label file")
    if output.exists():
        raise ValueError(
            f"label file {output} already exists; choose another --output or remove it"
        )
    if (directory / DB_NAME).is_file():
        db = LabelDB(directory / DB_NAME)
        try:
            _check_agreed(db, agreed_by)
            return export_file(db, output, agreed_by), str(directory / DB_NAME)
        finally:
            db.close()
    if agreed_by is not None and (directory / "config.json").is_file():
        raise ValueError(
            f"{directory} is a run directory, whose teacher answered each pair once; "
            "--agreed-by reads a team's labelling directory (labels.sqlite)"
        )
    if not (directory / "config.json").is_file():
        raise ValueError(
            f"{directory} holds no {DB_NAME} (a labelling directory) nor config.json "
            "(a run directory)"
        )
    return _export_run(directory, output), f"run {directory}"


def _all_keep_states(path: Path) -> bool:
    """Whether every segment of the label file keeps the physics states its clip needs."""
    from seqrank.feedback.label_file import read_label_file

    segments = read_label_file(path).segments.values()
    return all(segment.get("states") is not None for segment in segments)


def _check_agreed(db: Any, agreed_by: int | None) -> None:
    """Refuses an agreed-pairs export that would hold no pair."""
    from seqrank.labelling.jsonl import agreed_pairs

    if agreed_by is not None and not agreed_pairs(db.answered_questions(), agreed_by):
        raise ValueError(
            f"no pair of {db.path} was answered alike by {agreed_by} or more people "
            "(a team's second opinions make such pairs); nothing written"
        )


def _export_run(directory: Path, output: Path) -> int:
    import os

    from seqrank.envs import make_env
    from seqrank.feedback.label_file import store_lines
    from seqrank.feedback.labels import LabelStore
    from seqrank.training.runs import RunDir

    run = RunDir.open(directory)
    config = run.read_config()
    state = run.load_checkpoint()
    store = LabelStore()
    if state is not None:
        store.load_state_dict(state["labels"])
    env = make_env(config.task, config.seed)
    header = {
        "task": config.task,
        "obs_dim": env.obs_dim,
        "act_dim": env.act_dim,
        "segment_length": config.segment_length,
    }
    env.close()
    lines = list(store_lines(store, header, "train", config.scheme.value, config.teacher))
    output.parent.mkdir(parents=True, exist_ok=True)
    partial = output.with_name(output.name + ".part")
    partial.write_text("".join(line + "\n" for line in lines))
    os.replace(partial, output)
    return sum('"type": "answer"' in line for line in lines)


def _import(file: Path, directory: Path) -> tuple[int, Path]:
    from seqrank.feedback.label_file import read_label_file
    from seqrank.labelling.db import DB_NAME, LabelDB
    from seqrank.labelling.directory import take_directory
    from seqrank.labelling.jsonl import import_file

    read_label_file(file)  # a bad file is refused before anything is made
    with take_directory(directory):
        db = LabelDB(directory / DB_NAME)
        try:
            return import_file(db, file), directory / DB_NAME
        finally:
            db.close()
