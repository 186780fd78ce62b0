"""What the sub-commands share: the parser class, value parsers and the training options."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from dataclasses import Field, fields
from pathlib import Path
from typing import Any, NoReturn

from seqrank.cli.option_help import MEANINGS
from seqrank.config import SCALES, TrainConfig
from seqrank.errors import SettingError

# TrainConfig field annotations (strings under `from __future__ import annotations`) -> types.
FIELD_TYPES: dict[str, type] = {"int": int, "float": float, "str": str}


class Parser(argparse.ArgumentParser):
    """Bad input: one line naming the problem and the command it belongs to, exit code 2.
    Options are never abbreviated: `--schem` is no `--scheme`, and `--annotator` no
    `--annotators` (a prefix silently taken for another option changed runs)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace | None, list[str]]:
        """A command without sub-commands of its own names an unknown option itself, not
        the top-level `seqrank` that would otherwise report it."""
        namespace, extras = super().parse_known_args(args, namespace)
        if extras and self._subparsers is None:
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return namespace, extras

    def _check_value(self, action: argparse.Action, value: Any) -> None:
        """Choices as the user types them (an enum's value, not its repr)."""
        if action.choices is not None and value not in action.choices:
            accepted = ", ".join(str(choice) for choice in action.choices)
            message = f"invalid choice: {value!r}; accepted: {accepted}"
            raise argparse.ArgumentError(action, message)


def _whole_number(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None


def int_at_least(minimum: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        value = _whole_number(text)
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{value} is too small; it must be >= {minimum}")
        return value

    return parse


def int_between(low: int, high: int, what: str = "") -> Callable[[str], int]:
    """A whole number in [low, high]; `what` says why the range is what it is."""

    def parse(text: str) -> int:
        value = _whole_number(text)
        if not low <= value <= high:
            why = f" ({what})" if what else ""
            raise argparse.ArgumentTypeError(
                f"{value} is out of range; accepted: {low} to {high}{why}"
            )
        return value

    return parse


def number_between(low: float, high: float) -> Callable[[str], float]:
    """A finite number in [low, high]."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not low <= value <= high:  # also refuses nan
            raise argparse.ArgumentTypeError(
                f"{value} is out of range; accepted: {low:g} to {high:g}"
            )
        return value

    return parse


# a seed: what numpy, torch and the simulators accept; a TCP port (0: any free one); a
# rendered frame's side (MuJoCo's offscreen framebuffer is 640 x 480)
seed_number = int_between(0, 2**32 - 1)
port_number = int_between(0, 65535, "0 picks a free port")
frame_size = int_between(16, 480, "the simulators render at most 480 pixels a side")


def positive(text: str) -> int:
    value = _whole_number(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


def probability(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"{value} must lie strictly between 0 and 1")
    return value


def split_names(text: str, accepted: Sequence[str], what: str) -> list[str]:
    """Comma-separated names, each from `accepted`, without repeats; else ValueError."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in accepted]
    if unknown or not names:
        bad = ", ".join(repr(n) for n in unknown) or repr(text)
        raise ValueError(f"unknown {what} {bad}; accepted: {', '.join(accepted)} (comma-separated)")
    return list(dict.fromkeys(names))


def names(accepted: Sequence[str], what: str) -> Callable[[str], list[str]]:
    def parse(text: str) -> list[str]:
        try:
            return split_names(text, accepted, what)
        except ValueError as problem:
            raise argparse.ArgumentTypeError(str(problem)) from None

    return parse


def field_type(field: Field[Any]) -> type:
    """A TrainConfig field's type on the command line: int, float, or else str (a named
    choice such as the scheme is given as its name, and the config checks it)."""
    return FIELD_TYPES.get(str(field.type), str)


def setting_flags(parser: argparse.ArgumentParser) -> frozenset[str]:
    """The settings (TrainConfig fields) that `parser` has as options; a command keeps
    them as its `setting_flags` default, for `problem_with_flags`."""
    names = {f.name for f in fields(TrainConfig)}
    return frozenset(action.dest for action in parser._actions if action.dest in names)


def problem_with_flags(problem: Exception, args: argparse.Namespace) -> str:
    """An error's message with the settings it names spelled as the options the user can
    have typed (`knn_k` -> `--knn-k`): the command's own setting options, none when it
    resumes a run (its settings come from config.json). Other errors as they are."""
    if not isinstance(problem, SettingError):
        return str(problem)
    if hasattr(args, "resume"):
        return f"{problem} (the run's settings, saved in {args.resume}/config.json)"
    typed: frozenset[str] = getattr(args, "setting_flags", frozenset())
    return problem.spelled(lambda name: f"--{name.replace('_', '-')}" if name in typed else name)


def given_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The TrainConfig fields given on the command line (the others are absent from args)."""
    return {f.name: getattr(args, f.name) for f in fields(TrainConfig) if hasattr(args, f.name)}


def add_run_options(parser: argparse.ArgumentParser, wandb: bool = True) -> None:
    """--scale, --out, --resume, --wandb (unless `wandb` is False) and one option per
    TrainConfig field."""
    if wandb:
        parser.add_argument(
            "--wandb",
            metavar="PROJECT",
            default=argparse.SUPPRESS,
            help="also log the metrics to this Weights & Biases project (WANDB_MODE=offline "
            "keeps them on disk); needs pip install 'seqrank[wandb]'",
        )
    parser.add_argument(
        "--scale",
        choices=("auto", *SCALES),
        default=argparse.SUPPRESS,
        help="paper: Table 2 sizes; small: a 2-core CPU preset; auto (default): paper on "
        "CUDA, small on CPU",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=argparse.SUPPRESS,
        help="run directory (default: seqrank-out/runs/<task>_<scheme>_...)",
    )
    parser.add_argument(
        "--resume",
        type=Path,
        metavar="RUN_DIR",
        default=argparse.SUPPRESS,
        help="continue a stopped run from its last checkpoint",
    )
    parser.add_argument(
        "--dry-run",
        action="store_true",
        help="check the settings and print them (or the state of --resume's run); write nothing",
    )
    for f in fields(TrainConfig):
        if f.name == "scale":
            continue
        parser.add_argument(
            f"--{f.name.replace('_', '-')}",
            type=field_type(f),
            default=argparse.SUPPRESS,
            metavar=field_type(f).__name__.upper(),
            help=f"{MEANINGS.get(f.name, '')} (default: {f.default or 'none'} or the preset's)",
        )
    parser.set_defaults(setting_flags=setting_flags(parser))
