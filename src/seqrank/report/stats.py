"""Statistics for comparing schemes over few seeds (after Agarwal et al., NeurIPS 2021).

- IQM: the interquartile mean, the mean of the middle 50% of scores (25% trimmed each side).
- Stratified bootstrap: resample the runs of each task with replacement, separately, and
  recompute the statistic on the pooled resample; the 2.5 and 97.5 percentiles give a 95% CI.
- Probability of improvement P(X > Y): per task, the chance that a random run of X beats a
  random run of Y (ties count half; the Mann-Whitney U statistic over mn), averaged over tasks.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
from scipy import stats

Scores = Mapping[str, np.ndarray]  # task -> scores of its runs (one per seed)


def iqm(values: np.ndarray) -> float:
    return float(stats.trim_mean(np.asarray(values, np.float64), 0.25))


def pooled_iqm(scores: Scores) -> float:
    return iqm(np.concatenate([np.asarray(v, np.float64) for v in scores.values()]))


def probability_of_improvement(x: Scores, y: Scores) -> float:
    """Average over the tasks both have of P(a run of x beats a run of y)."""
    tasks = [t for t in x if t in y and len(x[t]) and len(y[t])]
    if not tasks:
        raise ValueError("no task has runs of both methods")
    per_task = []
    for task in tasks:
        a, b = np.asarray(x[task])[:, None], np.asarray(y[task])[None, :]
        per_task.append(float(np.mean((a > b) + 0.5 * (a == b))))
    return float(np.mean(per_task))


def stratified_bootstrap_ci(
    statistic: Callable[..., float],
    groups: tuple[Scores, ...],
    repetitions: int,
    rng: np.random.Generator,
    level: float = 0.95,
) -> tuple[float, float]:
    """CI of `statistic(*groups)` resampling each (group, task) independently."""
    values = np.empty(repetitions)
    for k in range(repetitions):
        resampled = tuple(
            {t: v[rng.integers(len(v), size=len(v))] for t, v in group.items() if len(v)}
            for group in groups
        )
        values[k] = statistic(*resampled)
    tail = 100 * (1 - level) / 2
    low, high = np.percentile(values, [tail, 100 - tail])
    return float(low), float(high)


def interval(values: list[float]) -> tuple[float, float, float]:
    """Mean and its 95% t-interval over seeds (the mean twice for a single seed)."""
    array = np.asarray(values, np.float64)
    mean = float(array.mean())
    if len(array) < 2:
        return mean, mean, mean
    half = float(stats.t.ppf(0.975, len(array) - 1) * array.std(ddof=1) / np.sqrt(len(array)))
    return mean, mean - half, mean + half
