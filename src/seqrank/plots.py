"""PNG plots (matplotlib, headless)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from seqrank.simulate import CellResult


def plot_simulation(results: Sequence[CellResult], path: Path) -> None:
    """Grouped bars per teacher: pairs per question, inferred error rate, max degree."""
    schemes = list(dict.fromkeys(_series(r) for r in results))
    teachers = list(dict.fromkeys(r.teacher for r in results))
    by_cell = {(_series(r), r.teacher): r for r in results}
    panels: list[tuple[str, Callable[[CellResult], float]]] = [
        ("labelled pairs per question", lambda r: r.pairs_per_question),
        ("error rate of inferred pairs", lambda r: r.inferred_error_rate or 0.0),
        ("max dependency degree", lambda r: r.max_degree),
    ]
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4), constrained_layout=True)
    width = 0.8 / len(schemes)
    for axis, (title, metric) in zip(axes, panels, strict=True):
        for k, scheme in enumerate(schemes):
            xs = [i + (k - (len(schemes) - 1) / 2) * width for i in range(len(teachers))]
            ys = [metric(by_cell[(scheme, t)]) for t in teachers]
            axis.bar(xs, ys, width=width, label=scheme)
        axis.set_xticks(range(len(teachers)), teachers, rotation=30)
        axis.set_title(title)
        axis.grid(axis="y", alpha=0.3)
    axes[0].legend()
    first = results[0]
    fig.suptitle(f"{first.questions} questions per session, {first.sessions} sessions per cell")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _series(result: CellResult) -> str:
    full = result.augment == "full"
    return result.scheme if full else f"{result.scheme} ({result.augment})"


def plot_curve(curve: Sequence[tuple[int, float]], path: Path, title: str) -> None:
    """Evaluation return against environment steps."""
    fig, axis = plt.subplots(figsize=(6, 4), constrained_layout=True)
    axis.plot([s for s, _ in curve], [r for _, r in curve], marker="o")
    axis.set_xlabel("environment steps")
    axis.set_ylabel("evaluation return")
    axis.set_title(title)
    axis.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)
