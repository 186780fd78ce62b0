"""Errors the CLI turns into one line on stderr and exit code 2."""

from __future__ import annotations

import re
from collections.abc import Callable
from enum import StrEnum
from typing import TypeVar

# marks a setting's name inside a SettingError's message (never shown: str() spells it)
_MARK = "\x00"
_MARKED = re.compile(f"{_MARK}(\\w+){_MARK}")


class UsageError(Exception):
    """Bad input from the user: the message names the value and what is accepted."""


def setting(name: str) -> str:
    """`name` as a setting inside a SettingError's message, for each front end to spell."""
    return f"{_MARK}{name}{_MARK}"


class SettingError(ValueError):
    """A setting out of its range, or settings that do not go together.

    Each setting the message names is marked with `setting(name)`, because the user wrote
    it differently depending on where: the exception's text (`str`, `args`) names it as
    the setting itself (sweep files, the Python API); `spelled` lets a command name it as
    its option (`--knn-k`)."""

    def __init__(self, marked: str):
        super().__init__(_MARKED.sub(r"\1", marked))
        self.marked = marked  # kept through pickling (a sweep worker's error)

    def spelled(self, spell: Callable[[str], str]) -> str:
        return _MARKED.sub(lambda found: spell(found.group(1)), self.marked)


Choice = TypeVar("Choice", bound=StrEnum)


def parse_choice(kind: type[Choice], value: object, what: str) -> Choice:
    """`value` as a member of `kind`; a SettingError names the bad value and what is
    accepted (`what`: the setting's name)."""
    try:
        return kind(str(value)) if isinstance(value, str) else kind(value)  # type: ignore[arg-type]
    except ValueError:
        accepted = ", ".join(member.value for member in kind)
        raise SettingError(f"unknown {setting(what)} {value!r}; accepted: {accepted}") from None
