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
from pathlib import Path
from typing import Any

from seqrank.choices import RewardSignal
from seqrank.config import unread_settings
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
            split[run.path] = (
                name + "/" + ",".join(f"{k}={_text(run.settings.get(k))}" for k in keys)
            )
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
    keys = {key for run in members for key in run.settings} - ignored
    return sorted(k for k in keys if len({repr(run.settings.get(k)) for run in members}) > 1)


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
