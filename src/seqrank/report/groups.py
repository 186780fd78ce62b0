"""Runs of one report cell (task and method) that differ in other settings are kept apart.

A folder can hold runs of one method made with other settings (a sweep's variants, a run
made by hand with more feedback, a sweep file changed between runs). Their scores are not
pooled silently: each setting in which a cell's runs differ joins their method name
(`sequential/max_feedback=100`), and the report says so in a note. A baseline's runs differ
only in the settings it reads (`config.unread_settings`): a sweep's variants of feedback
settings give one true-reward method, and a seed it ran once per variant counts once.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import MISSING, fields
from enum import Enum
from functools import cache
from pathlib import Path
from typing import Any

from seqrank.choices import RewardSignal
from seqrank.config import TrainConfig, unread_settings
from seqrank.config.rules import CROWD_SETTINGS, crowd_settings_unread_by
from seqrank.offline.settings import OfflineConfig
from seqrank.report.collect import RunResult

# settings that do not change what a run learns, or are already in the method's name
SAME_METHOD = {
    "seed",
    "device",
    "path",
    "checkpoint_every",
    "heldout_pairs",
    "record_states",
    "task",
    "scheme",
    "backbone",
    "teacher",
    "scale",
    "reward",
    "augment",
    "reward_learner",
    "warm_start",
    "segment_order",
}
# settings only one reward learner reads: runs of another learner may hold any value (or,
# made before the setting existed, none)
LEARNER_PREFIXES = {"surf": "surf_", "rime": "rime_"}
# settings only `augment checked` reads (their defaults changed once: twice_gain 20 -> 5)
CHECKED_ONLY = {"recheck_gain", "recheck_twice_gain", "path_unchecked"}


def split_by_settings(
    runs: list[RunResult], names: dict[Path, str]
) -> tuple[dict[Path, str], list[str]]:
    """Method names with the settings that differ inside a cell, and a note per split cell."""
    cells: dict[tuple[str, str], list[RunResult]] = defaultdict(list)
    for run in runs:
        cells[(run.task, names[run.path])].append(run)
    split, notes = dict(names), []
    for (task, name), members in sorted(cells.items()):
        keys = _differing(members)
        if not keys:
            continue
        for run in members:
            split[run.path] = name + "/" + ",".join(f"{k}={_text(_as_read(run, k))}" for k in keys)
        parts = sorted({split[run.path] for run in members})
        notes.append(
            f"{task}: {name} runs differ in {', '.join(keys)}; reported apart as "
            + ", ".join(parts)
        )
    return split, notes


def _differing(members: list[RunResult]) -> list[str]:
    ignored = set(_never_splitting(members[0]))  # a copy: it grows below
    learner = members[0].settings.get("reward_learner", "plain")  # one per cell
    ignored |= {
        key
        for run in members
        for key in run.settings
        for name, prefix in LEARNER_PREFIXES.items()
        if key.startswith(prefix) and name != learner
    }
    if members[0].settings.get("augment", "full") != "checked":  # one per cell
        ignored |= CHECKED_ONLY
    ignored |= frozenset.intersection(*(_crowd_unread(run) for run in members))
    keys = {key for run in members for key in run.settings} - ignored
    return sorted(k for k in keys if len({repr(_as_read(run, k)) for run in members}) > 1)


def _crowd_unread(run: RunResult) -> frozenset[str]:
    if not run.teacher:  # an offline true-reward run records none: it asks nobody
        return frozenset(CROWD_SETTINGS)
    return crowd_settings_unread_by(run.teacher, run.settings.get("annotators") or "")


def _as_read(run: RunResult, key: str) -> Any:
    """A run's setting as the run reads it: absent from an older config.json, today's
    default (what `Run.read_config` and `OfflineConfig.from_dict` fill in)."""
    if key in run.settings:
        return run.settings[key]
    return _defaults(bool(run.settings.get("dataset"))).get(key)


@cache
def _defaults(offline: bool) -> dict[str, Any]:
    config = OfflineConfig if offline else TrainConfig
    # as config.json writes them: an enum by its value
    return {
        f.name: f.default.value if isinstance(f.default, Enum) else f.default
        for f in fields(config)
        if f.default is not MISSING
    }


def _never_splitting(run: RunResult) -> set[str]:
    """The settings that never split the cell of `run`: for a baseline, also those it never
    reads."""
    if not run.baseline:
        return SAME_METHOD
    start_from = bool(run.settings.get("start_from"))
    return SAME_METHOD | unread_settings(RewardSignal(run.reward), start_from)


def one_run_per_seed(
    runs: list[RunResult], names: dict[Path, str]
) -> tuple[list[RunResult], list[str]]:
    """The runs with one baseline run per task, method and seed, and a note per method that
    had more: runs alike in every setting a baseline reads (a sweep ran it once per variant)
    are one measurement, not more seeds."""
    alike: dict[tuple[str, str, int], list[RunResult]] = defaultdict(list)
    for run in runs:
        if run.baseline:
            alike[(run.task, names[run.path], run.seed)].append(run)
    repeats: dict[tuple[str, str], list[RunResult]] = defaultdict(list)
    for (task, name, _), members in sorted(alike.items()):
        members.sort(key=lambda r: (not r.finished, -r.steps, str(r.path)))
        repeats[(task, name)] += members[1:]
    dropped = {run.path for members in repeats.values() for run in members}
    notes = [
        f"{task}: {name} runs of a seed alike in every setting it reads count once; left "
        "out " + ", ".join(run.path.name for run in members)
        for (task, name), members in repeats.items()
        if members
    ]
    return [run for run in runs if run.path not in dropped], notes


def _text(value: Any) -> str:
    return "-" if value is None else f"{value:g}" if isinstance(value, float) else str(value)
