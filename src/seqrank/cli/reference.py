"""The command-line reference page, written from the parser itself.

`python -m seqrank.cli.reference > docs/reference/cli.md` rewrites the page; a test fails
when the committed page differs from what the parser says now, so the page cannot go stale.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Iterator

# Defaults that depend on the machine the page is written on: shown by what they mean.
MACHINE_DEFAULTS = {"--workers": "the number of cores"}

INTRO = """# Command line

Every sub-command of `seqrank` and every option, with its help and its default. This page
is written from the command's own parser (`python -m seqrank.cli.reference >
docs/reference/cli.md`), and a test fails when it is out of date. `seqrank COMMAND --help`
prints the same on a terminal.
"""


def parsers(
    parser: argparse.ArgumentParser, path: tuple[str, ...] = ()
) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser, str]]:
    """(words after `seqrank`, parser, one-line help) of every command, depth first."""
    yield path, parser, ""
    for action in parser._actions:
        if not isinstance(action, argparse._SubParsersAction):
            continue
        helps = {choice.dest: choice.help or "" for choice in action._choices_actions}
        for name, child in action.choices.items():
            for words, sub, summary in parsers(child, (*path, name)):
                yield words, sub, summary or (helps.get(name, "") if words == (*path, name) else "")


def _default(action: argparse.Action) -> str:
    option = action.option_strings[-1] if action.option_strings else ""
    if option in MACHINE_DEFAULTS and action.default == (os.cpu_count() or 1):
        return MACHINE_DEFAULTS[option]
    if isinstance(action, argparse._StoreTrueAction | argparse._StoreFalseAction):
        return ""
    if action.default in (None, argparse.SUPPRESS, "", [], ()):
        return ""
    if isinstance(action.default, list | tuple):
        return "`" + ",".join(str(value) for value in action.default) + "`"
    return f"`{action.default}`"


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _option_row(action: argparse.Action) -> str:
    if action.option_strings:
        name = ", ".join(f"`{option}`" for option in action.option_strings)
        if action.nargs != 0:
            value = action.metavar or (action.dest.upper() if not action.choices else None)
            if action.choices and not action.metavar:
                value = "{" + ",".join(str(choice) for choice in action.choices) + "}"
            name += f" `{value}`"
    else:
        name = f"`{action.metavar or action.dest}`"
    help_text = (action.help or "") % {"default": action.default} if action.help else ""
    return f"| {_cell(name)} | {_cell(help_text)} | {_default(action)} |"


def command_section(words: tuple[str, ...], parser: argparse.ArgumentParser, summary: str) -> str:
    """One command's heading, description and table of options."""
    lines = [f"{'#' * min(len(words) + 1, 4)} `seqrank {' '.join(words)}`".rstrip(), ""]
    about = parser.description or summary
    if about:
        lines += [" ".join(about.split()), ""]
    rows = [
        _option_row(action)
        for action in parser._actions
        if action.help != argparse.SUPPRESS
        and not isinstance(action, argparse._SubParsersAction | argparse._HelpAction)
    ]
    if rows:
        lines += ["| option | what it does | default |", "|---|---|---|", *rows, ""]
    return "\n".join(lines)


def reference_page() -> str:
    """The whole page: every command that takes options, in the parser's order."""
    from seqrank.cli import build_parser

    sections = [
        command_section(words, parser, summary)
        for words, parser, summary in parsers(build_parser())
        if words
    ]
    return INTRO + "\n" + "\n".join(sections)


if __name__ == "__main__":
    sys.stdout.write(reference_page())
