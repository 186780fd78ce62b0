"""The reward benchmark's curves: each measure against what the questions cost, questions
asked, clips watched or an annotator's seconds (`summary.summarise`'s entries)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from seqrank.rewardbench.intervals import Interval
from seqrank.rewardbench.summary import MEASURES

# what a curve's x axis may be: a summary entry's key -> its axis label, the file name's
# suffix, and what the title says the model learns per
COSTS = {
    "questions": ("questions asked", "", "question"),
    "clips": ("clips watched", "_clips", "clip watched"),
    "annotator_seconds": (
        "annotator seconds (clips played + 3 s a question)",
        "_seconds",
        "annotator second",
    ),
}


def _band(value: Interval) -> tuple[float, float, float]:
    """A curve's point and its shaded band (no width for one seed)."""
    mean, low, high = value
    return mean, mean if low is None else low, mean if high is None else high


def curve_paths(summary: list[dict[str, Any]], task: str, folder: Path) -> dict[str, Path]:
    """The curves a task's entries can have, by x axis: `curves_<task>.png` against
    questions, `_clips` and `_seconds` beside it where the rows counted them."""
    entries = [e for e in summary if e["task"] == task]
    stem = f"curves_{task.replace(':', '-')}"
    return {
        cost: folder / f"{stem}{suffix}.png"
        for cost, (_, suffix, _) in COSTS.items()
        if any(e.get(cost) is not None for e in entries)
    }


def plot_task(
    summary: list[dict[str, Any]], task: str, path: Path, cost: str = "questions"
) -> Path:
    """Each measure against `cost` (a key of `COSTS`), one line per scheme (and learner,
    when there are several) with its 95% interval shaded, one row of panels per teacher."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    entries = [e for e in summary if e["task"] == task and e.get(cost) is not None]
    teachers = list(dict.fromkeys(e["teacher"] for e in entries))
    # one colour per line in every panel; a line's learner named when there are several
    lines = list(dict.fromkeys((e["scheme"], e["learner"]) for e in entries))
    several = len({e["learner"] for e in entries}) > 1
    figure, axes = plt.subplots(
        len(teachers),
        len(MEASURES),
        figsize=(4.6 * len(MEASURES), 3.6 * len(teachers)),
        squeeze=False,
    )
    for row, teacher in zip(axes, teachers, strict=True):
        for axis, (measure, title) in zip(row, MEASURES.items(), strict=True):
            mine = [e for e in entries if e["teacher"] == teacher]
            _panel(axis, mine, lines, several, (measure, cost))
            axis.set_title(f"{teacher}: {title}", fontsize=10)
            axis.set_xlabel(COSTS[cost][0])
            axis.grid(alpha=0.3)
            if axis.lines:
                axis.legend(fontsize=8)
    figure.suptitle(f"{task}: what the reward model learns per {COSTS[cost][2]} (95% intervals)")
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return path


def _panel(
    axis: Any,
    entries: list[dict[str, Any]],
    lines: list[tuple[str, str]],
    several: bool,
    what: tuple[str, str],
) -> None:
    """One teacher's `what` (measure, cost): a line per scheme and learner, its colour the
    line's place in `lines`."""
    measure, cost = what
    for k, (scheme, learner) in enumerate(lines):
        points = sorted(
            (e[cost], *_band(e[measure]))
            for e in entries
            if (e["scheme"], e["learner"]) == (scheme, learner) and e[measure]
        )
        if not points:
            continue
        x, mean, low, high = (np.array(column) for column in zip(*points, strict=True))
        label = f"{scheme} ({learner})" if several else scheme
        axis.plot(x, mean, marker="o", label=label, color=f"C{k % 10}")
        axis.fill_between(x, low, high, color=f"C{k % 10}", alpha=0.2)
