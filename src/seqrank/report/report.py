"""`seqrank report RUNS_DIR`: paper-style tables, robust statistics and plots.

Methods are schemes; when a folder mixes backbones, teachers or scales they join the method
name (`root/mrn/mistake/small`), and runs of one task and method that differ in any other
setting are kept apart, with the settings in their name and a note (`report/groups.py`).
Baseline runs (`--reward true` or `none`) are the methods `true-reward` and `no-feedback`;
with a true-reward run in the folder, every curve shows it as a reference line and every
method's score is also given relative to it. Outputs in
`--out` (default RUNS_DIR/report): `report.md`, `report.csv` (one row per task and method),
`report.json`, `curves_<task>.png` and `feedback_<task>.png`.
"""

from __future__ import annotations

import csv
import json
from collections import defaultdict
from collections.abc import Mapping
from itertools import permutations
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.choices import RewardSignal
from seqrank.report.collect import RunResult, collect_runs
from seqrank.report.groups import split_by_settings
from seqrank.report.stats import (
    Scores,
    iqm,
    pooled_iqm,
    probability_of_improvement,
    stratified_bootstrap_ci,
)

SCHEME_ORDER = ("pairwise", "sequential", "root", "ranked")
TRUE_REWARD = RewardSignal.TRUE.method
BASELINE_ORDER = (RewardSignal.NONE.method, TRUE_REWARD)
Cells = dict[tuple[str, str], list[RunResult]]  # (task, method) -> its runs with a score
Normalized = Mapping[str, Scores]  # method -> task -> normalized scores


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
    """`+checked`, `+surf` or `+rime`, `+warm`, `+qpa`: the options beyond the paper a run
    used."""
    marks = ""
    if settings.get("augment", "full") != "full":
        marks += f"+{settings['augment']}"
    if settings.get("reward_learner", "plain") != "plain":
        marks += f"+{settings['reward_learner']}"
    if settings.get("warm_start"):  # RIME's warm start, with any learner
        marks += "+warm"
    if settings.get("query_episodes") or settings.get("hybrid_replay"):
        marks += "+qpa"
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


def build_report(folder: Path, repetitions: int = 2000, seed: int = 0) -> dict[str, Any]:
    runs = collect_runs(folder)
    names, notes = split_by_settings(runs, method_names(runs))
    rng = np.random.default_rng(seed)
    tasks = sorted({r.task for r in runs})
    methods = _order(set(names.values()))
    cells: Cells = defaultdict(list)
    for run in runs:
        if run.score is not None:
            cells[(run.task, names[run.path])].append(run)
    table = _task_table(cells, tasks, methods, repetitions, rng)
    reference = reference_method(methods)
    if reference is not None:
        _add_relative(table, cells, reference, repetitions, rng)
    normalized = {
        method: {
            task: np.array([r.normalized for r in cells[(task, method)]], np.float64)
            for task in tasks
            if cells.get((task, method))
        }
        for method in methods
    }
    return {
        "folder": str(folder),
        "runs": len(runs),
        "finished": sum(r.finished for r in runs),
        "tasks": tasks,
        "methods": methods,
        "reference": reference,
        "table": table,
        "aggregate_iqm": _aggregate(normalized, methods, repetitions, rng),
        "probability_of_improvement": _improvement(normalized, methods, repetitions, rng),
        "bootstrap": {"repetitions": repetitions, "seed": seed},
        "notes": notes,
        "_runs": runs,
        "_names": names,
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
            low, high = stratified_bootstrap_ci(iqm_of, ({task: scores},), repetitions, rng)
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
        low, high = stratified_bootstrap_ci(iqm_ratio, (x, y), repetitions, rng)
        row.update(relative=iqm_ratio(x, y), relative_low=low, relative_high=high)


def iqm_ratio(x: Scores, y: Scores) -> float:
    return pooled_iqm(x) / pooled_iqm(y)


def _aggregate(
    normalized: Normalized, methods: list[str], repetitions: int, rng: np.random.Generator
) -> list[dict[str, Any]]:
    """Per method, the IQM of normalized scores pooled over tasks, with its bootstrap CI."""
    aggregate = []
    for method in methods:
        if not normalized[method]:
            continue
        low, high = stratified_bootstrap_ci(pooled_iqm, (normalized[method],), repetitions, rng)
        aggregate.append(
            {"method": method, "iqm": pooled_iqm(normalized[method]), "low": low, "high": high}
        )
    return aggregate


def _improvement(
    normalized: Normalized, methods: list[str], repetitions: int, rng: np.random.Generator
) -> list[dict[str, Any]]:
    """P(X > Y) for every ordered pair of methods sharing a task, with its bootstrap CI."""
    improvement = []
    for a, b in permutations(methods, 2):
        x, y = normalized[a], normalized[b]
        if not any(t in y for t in x):
            continue
        low, high = stratified_bootstrap_ci(probability_of_improvement, (x, y), repetitions, rng)
        improvement.append(
            {"x": a, "y": b, "p": probability_of_improvement(x, y), "low": low, "high": high}
        )
    return improvement


def iqm_of(scores: dict[str, np.ndarray]) -> float:
    return pooled_iqm(scores)


def format_markdown(report: dict[str, Any]) -> str:
    methods, tasks = report["methods"], report["tasks"]
    cell = {(row["task"], row["method"]): row for row in report["table"]}
    lines = [
        f"# Report: {report['folder']}",
        "",
        f"{report['runs']} runs ({report['finished']} finished; partial runs count with their "
        "last evaluation). Return on DMControl, success rate (%) on Meta-World and block:place;",
        "mean ± sample std over seeds (n), as in the paper's Tables 5-7.",
        *(f"Note: {note}." for note in report.get("notes", [])),
        "",
        "| task | " + " | ".join(methods) + " |",
        "|---|" + "---|" * len(methods),
    ]
    for task in tasks:
        row = [task]
        for method in methods:
            c = cell.get((task, method))
            if c is None:
                row.append("-")
                continue
            std = "" if c["std"] is None else f" ± {c['std']:.1f}"
            partial = f", {c['partial']} partial at step {c['steps']:,}" if c["partial"] else ""
            row.append(f"{c['mean']:.1f}{std} (n={c['n']}{partial})")
        lines.append("| " + " | ".join(row) + " |")
    lines += [
        "",
        "IQM per task with 95% bootstrap CI (runs resampled):",
        "",
        "| task | method | IQM | 95% CI |",
        "|---|---|---|---|",
    ]
    for c in report["table"]:
        lines.append(
            f"| {c['task']} | {c['method']} | {c['iqm']:.1f} | [{c['iqm_low']:.1f}, "
            f"{c['iqm_high']:.1f}] |"
        )
    lines += _relative_lines(report)
    lines += [
        "",
        "Aggregate IQM of normalized scores (DMControl return / 1000, success rate / 100) over "
        "all tasks, 95% stratified bootstrap CI:",
        "",
        "| method | IQM | 95% CI |",
        "|---|---|---|",
    ]
    for a in report["aggregate_iqm"]:
        lines.append(f"| {a['method']} | {a['iqm']:.3f} | [{a['low']:.3f}, {a['high']:.3f}] |")
    lines += [
        "",
        "Probability of improvement P(X > Y), averaged over tasks, 95% stratified bootstrap CI:",
        "",
        "| X | Y | P(X > Y) | 95% CI |",
        "|---|---|---|---|",
    ]
    for p in report["probability_of_improvement"]:
        lines.append(f"| {p['x']} | {p['y']} | {p['p']:.2f} | [{p['low']:.2f}, {p['high']:.2f}] |")
    boot = report["bootstrap"]
    lines += ["", f"Bootstrap: {boot['repetitions']} resamples, seed {boot['seed']}."]
    return "\n".join(lines) + "\n"


def _relative_lines(report: dict[str, Any]) -> list[str]:
    reference = report["reference"]
    rows = [c for c in report["table"] if c.get("relative") is not None]
    if reference is None or not rows:
        return []
    lines = [
        "",
        f"Score relative to the true-reward agent ({reference}): IQM / its IQM on the same "
        "task, 95% bootstrap CI (both resampled):",
        "",
        "| task | method | relative score | 95% CI |",
        "|---|---|---|---|",
    ]
    for c in rows:
        lines.append(
            f"| {c['task']} | {c['method']} | {c['relative']:.2f} | [{c['relative_low']:.2f}, "
            f"{c['relative_high']:.2f}] |"
        )
    return lines


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
