"""The `seqrank` command's entry point (`[project.scripts]` in pyproject.toml, and
`python -m seqrank`).

It imports nothing heavy itself: the command line, and with it torch, Gymnasium and the
rest (a second or more), is imported inside `main`'s `try`, so that Ctrl-C while they
load ends in one line, `interrupted`, and exit code 130 (SIGINT's, as every command
exits after Ctrl-C), not a traceback. From a command's own signal handling on (a run's
checkpoint first, the labelling page's export), the command says what a Ctrl-C did; an
interrupt that no command handles ends here the same way.
"""

from __future__ import annotations

import sys

INTERRUPTED = 130  # 128 + SIGINT


def main() -> int:
    try:
        from seqrank.cli import main as command_line

        return command_line()
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return INTERRUPTED
