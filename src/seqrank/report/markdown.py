"""`report.md`: the tables of a report (`report.build_report`), with what was counted and
how each task is scored said above them."""

from __future__ import annotations

from typing import Any

METRIC_TEXT = {"return": "return", "success": "success rate (%)"}


def format_markdown(report: dict[str, Any]) -> str:
    lines = [
        *_header(report),
        *_main_table(report),
        *_iqm_lines(report),
        *_relative_lines(report),
        *_aggregate_lines(report),
        *_improvement_lines(report),
    ]
    boot = report["bootstrap"]
    lines += ["", f"Bootstrap: {boot['repetitions']} resamples, seed {boot['seed']}."]
    return "\n".join(lines) + "\n"


def _header(report: dict[str, Any]) -> list[str]:
    counted = (
        f"{report['counted']} of {report['runs']} runs counted ({report['finished']} finished)"
    )
    return [
        f"# Report: {report['folder']}",
        "",
        f"{counted}; mean ± sample std over seeds (n), as in the paper's Tables 5-7.",
        _scored_by(report["table"]),
        *_unfinished_lines(report),
        *(f"Note: {note}." for note in report.get("notes", [])),
    ]


def _scored_by(table: list[dict[str, Any]]) -> str:
    """Which metric scores which task: success rate where the task has a success signal."""
    tasks: dict[str, list[str]] = {}
    for row in table:
        if row["task"] not in tasks.get(row["metric"], []):
            tasks.setdefault(row["metric"], []).append(row["task"])
    parts = [f"{METRIC_TEXT[m]} on {', '.join(tasks[m])}" for m in METRIC_TEXT if m in tasks]
    return f"Scored by {'; '.join(parts)}."


def _unfinished_lines(report: dict[str, Any]) -> list[str]:
    if report["include_unfinished"]:
        return [
            "Unfinished runs (no summary.json) count with their last evaluation: a cell or "
            "method marked `unfinished` holds some."
        ]
    left = report["left_out"]
    if not left:
        return []
    runs = ", ".join(f"{r['run']} (step {r['steps']:,} of {r['of']:,})" for r in left)
    return [
        f"Left out: {len(left)} unfinished run{'s' if len(left) > 1 else ''} (no summary.json: "
        f"stopped or still running; `--include-unfinished` counts them): {runs}."
    ]


def _main_table(report: dict[str, Any]) -> list[str]:
    methods = report["methods"]
    cell = {(row["task"], row["method"]): row for row in report["table"]}
    lines = ["", "| task | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for task in report["tasks"]:
        row = [task]
        for method in methods:
            c = cell.get((task, method))
            if c is None:
                row.append("-")
                continue
            std = "" if c["std"] is None else f" ± {c['std']:.1f}"
            partial = f", {c['partial']} unfinished at step {c['steps']:,}" if c["partial"] else ""
            row.append(f"{c['mean']:.1f}{std} (n={c['n']}{partial})")
        lines.append("| " + " | ".join(row) + " |")
    return lines


def _method(c: dict[str, Any]) -> str:
    return f"{c['method']} ({c['partial']} unfinished)" if c["partial"] else c["method"]


def _ci(low: float | None, high: float | None, digits: int) -> str:
    """An interval, or why there is none (a method with a single run on a task)."""
    if low is None or high is None:
        return "none (one run)"
    return f"[{low:.{digits}f}, {high:.{digits}f}]"


def _section(intro: str, columns: list[str], rows: list[list[str]]) -> list[str]:
    """A titled markdown table."""
    head = ["", intro, "", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    return head + ["| " + " | ".join(row) + " |" for row in rows]


def _iqm_lines(report: dict[str, Any]) -> list[str]:
    rows = [
        [c["task"], _method(c), f"{c['iqm']:.1f}", _ci(c["iqm_low"], c["iqm_high"], 1)]
        for c in report["table"]
    ]
    intro = "IQM per task with 95% bootstrap CI (runs resampled):"
    return _section(intro, ["task", "method", "IQM", "95% CI"], rows)


def _relative_lines(report: dict[str, Any]) -> list[str]:
    reference = report["reference"]
    cells = [c for c in report["table"] if c.get("relative") is not None]
    if reference is None or not cells:
        return []
    rows = [
        [
            c["task"],
            _method(c),
            f"{c['relative']:.2f}",
            _ci(c["relative_low"], c["relative_high"], 2),
        ]
        for c in cells
    ]
    intro = (
        f"Score relative to the true-reward agent ({reference}): IQM / its IQM on the same "
        "task, 95% bootstrap CI (both resampled):"
    )
    return _section(intro, ["task", "method", "relative score", "95% CI"], rows)


def _aggregate_lines(report: dict[str, Any]) -> list[str]:
    left_out = report["aggregate_left_out"]
    without = (
        f" (leaves out {', '.join(left_out)}: returns of a range nothing tells)" if left_out else ""
    )
    intro = (
        "Aggregate IQM of normalized scores (DMControl return / 1000, success rate / 100) over "
        f"the tasks{without}, 95% stratified bootstrap CI:"
    )
    rows = [
        [a["method"], f"{a['iqm']:.3f}", _ci(a["low"], a["high"], 3)]
        for a in report["aggregate_iqm"]
    ]
    return _section(intro, ["method", "IQM", "95% CI"], rows)


def _improvement_lines(report: dict[str, Any]) -> list[str]:
    rows = [
        [p["x"], p["y"], f"{p['p']:.2f}", _ci(p["low"], p["high"], 2)]
        for p in report["probability_of_improvement"]
    ]
    intro = "Probability of improvement P(X > Y), averaged over tasks, 95% stratified bootstrap CI:"
    return _section(intro, ["X", "Y", "P(X > Y)", "95% CI"], rows)
