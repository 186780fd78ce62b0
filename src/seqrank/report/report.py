"""`seqrank report RUNS_DIR`: paper-style tables, robust statistics and plots.

Methods are schemes; when a folder mixes backbones, teachers or scales they join the method
name (`root/mrn/mistake/small`), and runs of one task and method that differ in any other
setting are kept apart, with the settings in their name and a note (`report/groups.py`).
Baseline runs (`--reward true` or `none`) are the methods `true-reward` and `no-feedback`;
with a true-reward run in the folder, every curve shows it as a reference line and every
method's score is also given relative to it. A task is scored by success rate where it has
a success signal, by return elsewhere (`envs/scoring.py`); unfinished runs are left out
unless `include_unfinished` (and named). Outputs in
`--out` (default RUNS_DIR/report): `report.md`, `report.csv` (one row per task and method),
`report.json`, `curves_<task>.png` and `feedback_<task>.png`.
"""

from __future__ import annotations

import csv
import json
from collections import defaultdict
from collections.abc import Callable, Mapping
from itertools import permutations
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.choices import RewardSignal
from seqrank.report.collect import RunResult, collect_runs
from seqrank.report.groups import one_run_per_seed, split_by_settings
from seqrank.report.markdown import format_markdown
from seqrank.report.stats import (
    Scores,
    iqm,
    pooled_iqm,
    probability_of_improvement,
    stratified_bootstrap_ci,
)
from seqrank.report.sweep_plan import without_earlier_baselines

SCHEME_ORDER = ("pairwise", "sequential", "root", "ranked")
TRUE_REWARD = RewardSignal.TRUE.method
BASELINE_ORDER = (RewardSignal.NONE.method, TRUE_REWARD)
Cells = dict[tuple[str, str], list[RunResult]]  # (task, method) -> its runs with a score
PerMethod = Mapping[str, Scores]  # method -> task -> a score of each of its runs


def method_names(runs: list[RunResult]) -> dict[Path, str]:
    """Learned-reward runs are named by scheme, baselines by what they learn from
    (`true-reward`, `no-feedback`); a setting that varies across the folder joins the name."""
    learned = [r for r in runs if not r.baseline]
    vary_backbone = len({r.backbone for r in learned}) > 1
    vary_teacher = len({r.teacher for r in learned}) > 1
    vary_scale = len({r.scale for r in runs}) > 1
    names = {}
    for run in runs:
        if run.baseline:
            parts = [RewardSignal(run.reward).method]
        else:
            parts = [run.scheme + beyond_the_paper(run.settings)]
            if vary_backbone:
                parts.append(run.backbone)
            if vary_teacher:
                parts.append(run.teacher)
        if vary_scale:
            parts.append(run.scale)
        names[run.path] = "/".join(parts)
    return names


def beyond_the_paper(settings: Mapping[str, Any]) -> str:
    """`+checked`, `+surf` or `+rime`, `+warm`, `+qpa`, `+collection`: the options beyond
    the paper a run used."""
    marks = ""
    if settings.get("augment", "full") != "full":
        marks += f"+{settings['augment']}"
    if settings.get("reward_learner", "plain") != "plain":
        marks += f"+{settings['reward_learner']}"
    if settings.get("warm_start"):  # RIME's warm start, with any learner
        marks += "+warm"
    if settings.get("query_episodes") or settings.get("hybrid_replay"):
        marks += "+qpa"
    if settings.get("segment_order", "uniform") != "uniform":
        marks += f"+{settings['segment_order']}"  # (as the reward benchmark names it)
    return marks


def _order(methods: set[str]) -> list[str]:
    """Schemes in the paper's order, then other methods, then the baselines."""
    order = (*SCHEME_ORDER, "", *BASELINE_ORDER)

    def key(name: str) -> tuple[int, str]:
        first = name.split("/")[0]
        return order.index(first) if first in order else order.index(""), name

    return sorted(methods, key=key)


def reference_method(methods: list[str]) -> str | None:
    """The true-reward method that scores are set against, when the folder has one run of it
    (at one scale)."""
    references = [m for m in methods if m.split("/")[0] == TRUE_REWARD]
    return references[0] if len(references) == 1 else None


def build_report(
    folder: Path, repetitions: int = 2000, seed: int = 0, include_unfinished: bool = False
) -> dict[str, Any]:
    runs = collect_runs(folder)
    planned, earlier = without_earlier_baselines(runs, folder)
    counted, left_out = counted_runs(planned, include_unfinished, folder)
    names, notes = split_by_settings(counted, method_names(counted))
    counted, repeats = one_run_per_seed(counted, names)
    rng = np.random.default_rng(seed)
    tasks = sorted({r.task for r in counted})
    methods = _order({names[r.path] for r in counted})
    cells: Cells = defaultdict(list)
    for run in counted:
        if run.score is not None:
            cells[(run.task, names[run.path])].append(run)
    table = _task_table(cells, tasks, methods, repetitions, rng)
    reference = reference_method(methods)
    if reference is not None:
        _add_relative(table, cells, reference, repetitions, rng)
    normalized = _per_method(cells, tasks, methods, lambda r: r.normalized)
    unscaled = sorted({r.task for r in counted if r.score is not None and r.normalized is None})
    return {
        "folder": str(folder),
        "runs": len(runs),
        "finished": sum(r.finished for r in runs),
        "counted": len(counted),
        "include_unfinished": include_unfinished,
        "left_out": [_left_out(run, folder) for run in left_out],
        "tasks": tasks,
        "methods": methods,
        "reference": reference,
        "table": table,
        "aggregate_iqm": _aggregate(normalized, methods, repetitions, rng),
        "aggregate_left_out": unscaled,
        "probability_of_improvement": _improvement(
            _per_method(cells, tasks, methods, lambda r: r.score), methods, repetitions, rng
        ),
        "bootstrap": {"repetitions": repetitions, "seed": seed},
        "notes": earlier + notes + repeats,
        "_runs": counted,
        "_names": names,
    }


def counted_runs(
    runs: list[RunResult], include_unfinished: bool, folder: Path
) -> tuple[list[RunResult], list[RunResult]]:
    """The runs the tables count and those left out: an unfinished run's last evaluation
    is of fewer steps than the others', so it is counted only when asked for."""
    if include_unfinished:
        return runs, []
    counted = [r for r in runs if r.finished]
    if not counted:
        raise ValueError(
            f"{folder}: none of its {len(runs)} runs has finished (no summary.json); "
            "--include-unfinished reports them with their last evaluation"
        )
    return counted, [r for r in runs if not r.finished]


def _left_out(run: RunResult, folder: Path) -> dict[str, Any]:
    where = run.path.relative_to(folder) if run.path.is_relative_to(folder) else run.path
    return {"run": str(where), "task": run.task, "steps": run.steps, "of": run.total_steps}


def _per_method(
    cells: Cells, tasks: list[str], methods: list[str], value: Callable[[RunResult], float | None]
) -> PerMethod:
    """method -> task -> each run's `value`, for the tasks where it has one."""
    return {
        method: {
            task: np.array([value(r) for r in cells[(task, method)]], np.float64)
            for task in tasks
            if cells.get((task, method)) and value(cells[(task, method)][0]) is not None
        }
        for method in methods
    }


def _task_table(
    cells: Cells,
    tasks: list[str],
    methods: list[str],
    repetitions: int,
    rng: np.random.Generator,
) -> list[dict[str, Any]]:
    """One row per task and method with runs: mean, std and IQM with its bootstrap CI."""
    table = []
    for task in tasks:
        for method in methods:
            members = cells.get((task, method), [])
            if not members:
                continue
            scores = np.array([r.score for r in members], np.float64)
            low, high = _interval(iqm_of, ({task: scores},), repetitions, rng)
            table.append(
                {
                    "task": task,
                    "method": method,
                    "metric": members[0].metric,
                    "n": len(members),
                    "partial": sum(not r.finished for r in members),
                    "mean": float(scores.mean()),
                    "std": float(scores.std(ddof=1)) if len(scores) > 1 else None,
                    "iqm": iqm(scores),
                    "iqm_low": low,
                    "iqm_high": high,
                    "steps": min(r.steps for r in members),
                }
            )
    return table


def _add_relative(
    table: list[dict[str, Any]],
    cells: Cells,
    reference: str,
    repetitions: int,
    rng: np.random.Generator,
) -> None:
    """Each row's IQM as a fraction of the true-reward agent's IQM on its task, with a 95%
    bootstrap CI (both methods' runs resampled); left out where that IQM is not positive."""
    for row in table:
        row.update(relative=None, relative_low=None, relative_high=None)
        base = cells.get((row["task"], reference), [])
        if row["method"] == reference or not base:
            continue
        x = {row["task"]: np.array([r.score for r in cells[(row["task"], row["method"])]])}
        y = {row["task"]: np.array([r.score for r in base], np.float64)}
        if min(y[row["task"]]) <= 0:
            continue  # a ratio to a score at or below zero means nothing
        low, high = _interval(iqm_ratio, (x, y), repetitions, rng)
        row.update(relative=iqm_ratio(x, y), relative_low=low, relative_high=high)


def _interval(
    statistic: Callable[..., float],
    groups: tuple[Scores, ...],
    repetitions: int,
    rng: np.random.Generator,
) -> tuple[float | None, float | None]:
    """The stratified bootstrap CI, or none where a method has a single run on a task:
    resampling one run cannot show its spread, so the interval would be zero-wide there
    (or reflect the other method's runs only)."""
    if any(len(v) < 2 for group in groups for v in group.values()):
        return None, None
    return stratified_bootstrap_ci(statistic, groups, repetitions, rng)


def iqm_ratio(x: Scores, y: Scores) -> float:
    return pooled_iqm(x) / pooled_iqm(y)


def _aggregate(
    normalized: PerMethod, methods: list[str], repetitions: int, rng: np.random.Generator
) -> list[dict[str, Any]]:
    """Per method, the IQM of normalized scores pooled over tasks, with its bootstrap CI."""
    aggregate = []
    for method in methods:
        if not normalized[method]:
            continue
        low, high = _interval(pooled_iqm, (normalized[method],), repetitions, rng)
        aggregate.append(
            {"method": method, "iqm": pooled_iqm(normalized[method]), "low": low, "high": high}
        )
    return aggregate


def _improvement(
    scores: PerMethod, methods: list[str], repetitions: int, rng: np.random.Generator
) -> list[dict[str, Any]]:
    """P(X > Y) for every ordered pair of methods sharing a task, with its bootstrap CI (task
    by task, so on each task's own scale)."""
    improvement = []
    for a, b in permutations(methods, 2):
        x, y = scores[a], scores[b]
        if not any(t in y for t in x):
            continue
        low, high = _interval(probability_of_improvement, (x, y), repetitions, rng)
        improvement.append(
            {"x": a, "y": b, "p": probability_of_improvement(x, y), "low": low, "high": high}
        )
    return improvement


def iqm_of(scores: dict[str, np.ndarray]) -> float:
    return pooled_iqm(scores)


def write_report(report: dict[str, Any], out: Path, plots: bool = True) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "report.md", out / "report.csv", out / "report.json"]
    written[0].write_text(format_markdown(report))
    with written[1].open("w", newline="") as handle:
        fields = [
            "task",
            "method",
            "metric",
            "n",
            "partial",
            "mean",
            "std",
            "iqm",
            "iqm_low",
            "iqm_high",
            "steps",
            "relative",
            "relative_low",
            "relative_high",
        ]
        writer = csv.DictWriter(handle, fieldnames=fields, restval="")
        writer.writeheader()
        writer.writerows(report["table"])
    public = {k: v for k, v in report.items() if not k.startswith("_")}
    written[2].write_text(json.dumps(public, indent=2))
    if plots:
        from seqrank.report.plots import plot_curves, plot_feedback

        for task in report["tasks"]:
            runs = [r for r in report["_runs"] if r.task == task]
            slug = task.replace(":", "-")
            written.append(plot_curves(runs, report["_names"], task, out / f"curves_{slug}.png"))
            written.append(
                plot_feedback(runs, report["_names"], task, out / f"feedback_{slug}.png")
            )
    return written
