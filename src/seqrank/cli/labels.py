"""`seqrank labels export|import`: a labelling directory's answers as JSONL."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from rich.console import Console

from seqrank.cli.options import Parser
from seqrank.errors import UsageError


def add_parser(commands: Any) -> None:
    labels = commands.add_parser("labels", help="export or import labels as JSONL")
    actions = labels.add_subparsers(dest="action", required=True, parser_class=Parser)
    export = actions.add_parser("export", help="write a labelling directory's answers as JSONL")
    export.add_argument("directory", type=Path, help="holds labels.sqlite")
    export.add_argument("-o", "--output", type=Path, required=True)
    load = actions.add_parser("import", help="add a JSONL file's answers to a labelling directory")
    load.add_argument("file", type=Path)
    load.add_argument("directory", type=Path)
    labels.set_defaults(handler=run)


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.labelling.db import DB_NAME, LabelDB
    from seqrank.labelling.jsonl import export_file, import_file

    db_path = args.directory / DB_NAME
    try:
        if args.action == "export":
            if not db_path.exists():
                raise ValueError(f"{args.directory} holds no {DB_NAME}")
            count = export_file(LabelDB(db_path), args.output)
            out.print(f"{count} answers written to {args.output}")
        else:
            count = import_file(LabelDB(db_path), args.file)
            out.print(f"{count} answers added to {db_path}")
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    return 0
