"""Each numeric setting's own range (checked by `config.validate`; the rules settings
keep together are in `config_rules`)."""

from __future__ import annotations

import math
from typing import Any

from seqrank.errors import SettingError, setting

# The numeric settings' ranges: whole numbers from 1 (from 0 for these) to MAX_COUNT,
# numbers finite and > 0 (and at most 1 for these); the seed is what numpy, torch and the
# simulators accept.
MAX_COUNT = 2**31 - 1
MAX_SEED = 2**32 - 1
# settings whose size each feedback session allocates at once: a candidate pool this many
# times what the scheme needs, and this many held-out segment pairs
MAX = {
    "seed": MAX_SEED,
    "record_states": 1,
    "oversample": 100,
    "heldout_pairs": 100_000,
    "surf_unlabelled_ratio": 1_000,  # unlabelled pairs per question asked, cut each fit
    "surf_unlabelled_batch": 100,
    "warm_start": 1,
}
FROM_ZERO = (
    "seed",
    "seed_steps",
    "unsup_steps",
    "updates_after_reset",
    "record_states",
    "path_unchecked",
    "query_episodes",
    "hybrid_replay",
    "surf_crop",
    "warm_start",
    "overlap",
)
AT_MOST_ONE = (
    "overlap",
    "discount",
    "tau",
    "reward_stop_accuracy",
    "hybrid_replay",
    "surf_threshold",
    "rime_tau_upper",
)


def check_setting(name: str, kind: str, value: Any) -> None:
    """SettingError unless the numeric setting `name` (of type `kind`, "int" or "float")
    holds a value in its range."""
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise SettingError(
                f"{setting(name)} must be a whole number (an int), got {value!r} "
                f"({type(value).__name__})"
            )
        low = 0 if name in FROM_ZERO else 1
        high = MAX.get(name, MAX_COUNT)
        if not low <= value <= high:
            raise SettingError(
                f"{setting(name)} must be a whole number from {low} to {high}, got {value}"
            )
        return
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SettingError(
            f"{setting(name)} must be a number, got {value!r} ({type(value).__name__})"
        )
    unit, zero = name in AT_MOST_ONE, name in FROM_ZERO
    too_low = value < 0 or (value == 0 and not zero)
    if not math.isfinite(value) or too_low or (unit and value > 1):
        opening = "[0" if zero else "(0"
        accepted = f"a number in {opening}, 1]" if unit else "a finite number > 0"
        raise SettingError(f"{setting(name)} must be {accepted}, got {value}")
