"""Report figures: learning curves and feedback efficiency, one PNG per task."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from seqrank.report.collect import RunResult

# the baselines are reference lines: the true-reward agent above, the no-feedback floor below
BASELINE_STYLE: dict[str, tuple[str, str]] = {
    "true-reward": ("black", "--"),
    "no-feedback": ("grey", ":"),
}


def _by_method(runs: list[RunResult], names: dict[Path, str]) -> dict[str, list[RunResult]]:
    grouped: dict[str, list[RunResult]] = defaultdict(list)
    for run in runs:
        grouped[names[run.path]].append(run)
    return dict(sorted(grouped.items()))


def _band(points: dict[int, list[float]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps, mean and the half-width of a normal 95% interval of the mean (0 for one run)."""
    steps = np.array(sorted(points))
    means = np.array([np.mean(points[s]) for s in steps])
    half = np.array(
        [
            1.96 * np.std(points[s], ddof=1) / np.sqrt(len(points[s]))
            if len(points[s]) > 1
            else 0.0
            for s in steps
        ]
    )
    return steps, means, half


def plot_curves(runs: list[RunResult], names: dict[Path, str], task: str, path: Path) -> Path:
    """Evaluation return (or success) by step, one line per method, 95% interval shaded."""
    metric = runs[0].metric
    figure, axis = plt.subplots(figsize=(6.4, 4.2))
    for method, members in _by_method(runs, names).items():
        points: dict[int, list[float]] = defaultdict(list)
        for run in members:
            for step, ret, success in run.curve:
                points[step].append(ret if metric == "return" else success)
        if not points:
            continue
        steps, means, half = _band(points)
        low, high = means - half, means + half
        if metric != "return":
            low, high = np.clip(low, 0, 100), np.clip(high, 0, 100)
        color, dash = BASELINE_STYLE.get(method.split("/")[0], (None, "-"))
        label = f"{method} (n={len(members)})"
        (line,) = axis.plot(steps, means, label=label, color=color, linestyle=dash)
        axis.fill_between(steps, low, high, color=line.get_color(), alpha=0.2)
    axis.set_xlabel("environment steps")
    axis.set_ylabel("evaluation return" if metric == "return" else "success rate (%)")
    axis.set_title(f"{task}: mean over seeds, 95% interval of the mean")
    axis.grid(alpha=0.3)
    axis.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path


def plot_feedback(runs: list[RunResult], names: dict[Path, str], task: str, path: Path) -> Path:
    """Labelled pairs per question asked, and held-out reward accuracy, against questions."""
    figure, (pairs_axis, accuracy_axis) = plt.subplots(1, 2, figsize=(10, 4))
    for method, members in _by_method(runs, names).items():
        ratio: dict[int, list[float]] = defaultdict(list)
        accuracy: dict[int, list[float]] = defaultdict(list)
        for run in members:
            for row in run.feedback:
                asked = int(row.get("total_asked", 0))
                if asked:
                    ratio[asked].append(float(row.get("total_pairs", 0)) / asked)
                if row.get("reward_heldout_accuracy") is not None:
                    accuracy[asked].append(float(row["reward_heldout_accuracy"]))
        for axis, points in ((pairs_axis, ratio), (accuracy_axis, accuracy)):
            if points:
                steps, means, half = _band(points)
                (line,) = axis.plot(steps, means, marker="o", label=method)
                axis.fill_between(
                    steps, means - half, means + half, color=line.get_color(), alpha=0.2
                )
    pairs_axis.set_ylabel("labelled pairs per question (asked + inferred)")
    accuracy_axis.set_ylabel("reward model held-out accuracy")
    for axis in (pairs_axis, accuracy_axis):
        axis.set_xlabel("questions asked")
        axis.grid(alpha=0.3)
        axis.legend()
    figure.suptitle(f"{task}: feedback efficiency")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
