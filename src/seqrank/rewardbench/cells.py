"""A reward-benchmark cell's identity: the grid's axes, a row's cell, and which rows are
the same cell (light: the report reads these without torch)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from seqrank.choices import SegmentOrder

# the grid's axes besides task and seed, with the value a row written before the axis
# existed stands for (a new axis: a `Cell` field, an entry here, a `_row` key)
AXES = {
    "scheme": None,
    "teacher": None,
    "learner": "plain",
    "augment": "full",
    "weighting": "reliability",
    "stop": "all",
    "order": "uniform",
}
# the values of the fitting controls (issue 46, item 2)
AUGMENTS = ("full", "checked", "none")  # none: closure off, the asked pairs alone
STOPS = ("all", "asked", "never")  # the early stop's accuracy over; never: every epoch
ORDERS = tuple(o.value for o in SegmentOrder)  # a session's new segments: as drawn, or as collected


@dataclass(frozen=True)
class Cell:
    scheme: str
    teacher: str
    seed: int
    learner: str = "plain"
    augment: str = "full"  # checked: noise-aware augmentation (seqrank.feedback.checking)
    weighting: str = "reliability"  # a crowd's labels (`--crowd-weighting`): or none
    # the early stop's train accuracy counted over all labels (a run's rule), over the
    # asked pairs only, or never (every one of the net's epochs)
    stop: str = "all"
    # a session's new segments as a run draws them, or the same in collection order
    # (`rewardbench.order`): an axis, not a setting, so that one folder pairs the two
    # orders seed by seed in effects.md and a grid's uniform cells need not run again
    order: str = "uniform"

    def key(self, task: str) -> tuple[Any, ...]:
        return _key(task, {axis: getattr(self, axis) for axis in AXES}, self.seed)


def row_key(row: dict[str, Any]) -> tuple[Any, ...]:
    """The cell a row belongs to, as `Cell.key` gives it."""
    values = {axis: row.get(axis, default) for axis, default in AXES.items()}
    return _key(row["task"], values, row["seed"])


def weighs_labels(teacher: str) -> bool:
    """Only a crowd's labels are weighted by reliability: another teacher's cell is the
    same cell under every weighting, run and counted once."""
    return str(teacher).startswith("crowd:")


def _key(task: str, values: dict[str, Any], seed: int) -> tuple[Any, ...]:
    if not weighs_labels(values["teacher"]):
        values = {**values, "weighting": None}
    return (task, *values.values(), seed)


def distinct_rows(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Without the copies of a scripted teacher's cell under another weighting, which a
    folder written before such cells were run once holds. Two rows of one cell under the
    same weighting (folders merged by hand) both stay: the report names them."""
    weightings: dict[tuple[Any, ...], Any] = {}
    kept = []
    for row in rows:
        key = (*row_key(row), row["questions"])
        weighting = row.get("weighting", AXES["weighting"])
        if weightings.setdefault(key, weighting) == weighting:
            kept.append(row)
    return kept
