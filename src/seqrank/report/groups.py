"""Runs of one report cell (task and method) that differ in other settings are kept apart.

A folder can hold runs of one method made with other settings (a sweep's variants, a run
made by hand with more feedback, a sweep file changed between runs). Their scores are not
pooled silently: each setting in which a cell's runs differ joins their method name
(`sequential/max_feedback=100`), and the report says so in a note.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any

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
}
# settings a baseline run (which asks no questions) never uses
FEEDBACK_ONLY = {
    "selection",
    "oversample",
    "max_feedback",
    "reward_batch",
    "feedback_frequency",
    "segment_length",
    "episodes_kept",
    "query_episodes",
    "hybrid_replay",
    "hybrid_episodes",
    "meta_update_frequency",
    "meta_loss_weight",
    "augment",
    "recheck_gain",
    "recheck_twice_gain",
    "path_unchecked",
    "reward_learner",
    "surf_threshold",
    "surf_unlabelled_ratio",
    "surf_unlabelled_batch",
    "surf_loss_weight",
    "surf_crop",
    "rime_alpha",
    "rime_beta_max",
    "rime_beta_min",
    "rime_decay_updates",
    "rime_tau_upper",
    "rime_min_epochs",
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
    ignored = SAME_METHOD | (FEEDBACK_ONLY if members[0].baseline else set())
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


def _text(value: Any) -> str:
    return "-" if value is None else f"{value:g}" if isinstance(value, float) else str(value)
