"""How a task's runs are scored: by success rate where the task has a success signal, by
return where it has none; and what puts a score on a 0-1 scale across tasks.

Every environment puts `success` in `info`, and every evaluation row holds
`eval_success_rate`, so a rate of 0 alone does not tell a task that never succeeded from one
that cannot: the suite does (Meta-World and block:place have a signal, DMControl has none);
a Gymnasium or custom task has one when its `info` holds `success` or `is_success`, which
the runs show only by recording a success at some evaluation.
"""

from __future__ import annotations

from collections.abc import Iterable
from enum import StrEnum

from seqrank.envs.suites import SUITES, canonical_task

SUCCESS_SUITES = ("metaworld", "block")  # a success signal in every task
RETURN_SUITES = ("dmc",)  # no success signal: `info["success"]` is always False
DMC_MAX_RETURN = 1000.0  # rewards in [0, 1] over 1 000 steps


class Metric(StrEnum):
    RETURN = "return"  # the evaluation return
    SUCCESS = "success"  # the evaluation success rate, in percent


def task_metric(task: str, success_rates: Iterable[float]) -> Metric:
    """The metric of `task`, given the evaluation success rates (%) its runs recorded."""
    suite = _suite(task)
    if suite in SUCCESS_SUITES:
        return Metric.SUCCESS
    if suite in RETURN_SUITES or not any(rate > 0 for rate in success_rates):
        return Metric.RETURN
    return Metric.SUCCESS


def normalizing_scale(task: str, metric: Metric) -> float | None:
    """What a score is divided by to lie on 0-1: 100 for a success rate, 1 000 for a
    DMControl return; None for other returns, whose range nothing tells."""
    if metric is Metric.SUCCESS:
        return 100.0
    return DMC_MAX_RETURN if _suite(task) in RETURN_SUITES else None


def _suite(task: str) -> str:
    """The task's suite, without importing a Gymnasium plugin or a user's module (a report
    may be made where they are not installed)."""
    prefix = task.partition(":")[0] if ":" in task else ""
    if prefix == "gym" or (prefix and prefix not in SUITES):
        return "gym"
    return canonical_task(task)[0]
