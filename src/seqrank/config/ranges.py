"""The values a numeric setting accepts, declared with the setting (`TrainConfig`) and
checked by `validate`; the rules settings keep together are `config.rules`'."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from seqrank.errors import SettingError, setting

MAX_COUNT = 2**31 - 1
MAX_SEED = 2**32 - 1  # what numpy, torch and the simulators accept


@dataclass(frozen=True)
class Count:
    """An int setting: a whole number from `low` to `high`."""

    low: int = 1
    high: int = MAX_COUNT


@dataclass(frozen=True)
class Number:
    """A float setting: a finite number above 0 (or from 0), at most 1 where it is a
    share or a probability."""

    from_zero: bool = False
    at_most_one: bool = False


Accepted = Count | Number

COUNT = Count()
COUNT_FROM_ZERO = Count(low=0)
SWITCH = Count(low=0, high=1)  # 0 off, 1 on
POSITIVE = Number()
UP_TO_ONE = Number(at_most_one=True)  # (0, 1]
SHARE = Number(from_zero=True, at_most_one=True)  # [0, 1]


def check_setting(name: str, accepted: Accepted, value: Any) -> None:
    """SettingError unless the numeric setting `name` holds a value `accepted` takes."""
    if isinstance(accepted, Count):
        if isinstance(value, bool) or not isinstance(value, int):
            raise SettingError(
                f"{setting(name)} must be a whole number (an int), got {value!r} "
                f"({type(value).__name__})"
            )
        if not accepted.low <= value <= accepted.high:
            raise SettingError(
                f"{setting(name)} must be a whole number from {accepted.low} to "
                f"{accepted.high}, got {value}"
            )
        return
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SettingError(
            f"{setting(name)} must be a number, got {value!r} ({type(value).__name__})"
        )
    unit, zero = accepted.at_most_one, accepted.from_zero
    too_low = value < 0 or (value == 0 and not zero)
    if not math.isfinite(value) or too_low or (unit and value > 1):
        opening = "[0" if zero else "(0"
        accepted_text = f"a number in {opening}, 1]" if unit else "a finite number > 0"
        raise SettingError(f"{setting(name)} must be {accepted_text}, got {value}")
