"""`seqrank study-report`: the D.7 analysis over a study directory's participants.

Per method: satisfaction (1-5) and final evaluation return, mean and sample std over
participants, plus answer latency and time-outs; paired-sample t-tests (two-sided) between
every two methods on both, over the participants who finished both.
"""

from __future__ import annotations

import json
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from seqrank.labelling.db import DB_NAME, LabelDB


def study_report(study_dir: Path) -> dict[str, Any]:
    participants = sorted(p.parent for p in Path(study_dir).glob(f"*/{DB_NAME}"))
    if not participants:
        raise ValueError(f"{study_dir} holds no participant (no */{DB_NAME})")
    rows: dict[str, dict[str, dict[str, float]]] = {}
    methods: list[str] = []
    for directory in participants:
        db = LabelDB(directory / DB_NAME)
        try:
            surveys = {s["run"]: s for s in db.surveys()}
            answered = db.answered_questions()
        finally:
            db.close()
        order = _order(directory)
        methods += [m for m in order if m not in methods]
        per: dict[str, dict[str, float]] = {}
        for method in order:
            values: dict[str, float] = {}
            summary = directory / method / "summary.json"
            if summary.exists():
                final = json.loads(summary.read_text()).get("final_eval_return")
                if final is not None:
                    values["reward"] = float(final)
            if method in surveys:
                values["satisfaction"] = float(surveys[method]["satisfaction"])
            mine = [a for q, a in answered if q.run == method]
            if mine:
                values["latency_ms"] = float(np.mean([a.latency_ms for a in mine]))
                values["timeouts"] = float(sum(a.choice == "timeout" for a in mine))
                values["answers"] = float(len(mine))
            per[method] = values
        rows[directory.name] = per
    summary_rows = {m: _describe(rows, m) for m in methods}
    tests = [
        _paired(rows, a, b, metric)
        for metric in ("satisfaction", "reward")
        for a, b in combinations(methods, 2)
    ]
    return {"participants": rows, "methods": summary_rows, "tests": tests}


def _order(directory: Path) -> list[str]:
    path = directory / "study.json"
    if path.exists():
        order: list[str] = json.loads(path.read_text())["order"]
        return order
    return sorted(p.parent.name for p in directory.glob("*/config.json"))


def _describe(rows: dict[str, dict[str, dict[str, float]]], method: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for metric in ("satisfaction", "reward", "latency_ms", "timeouts"):
        values = [p[method][metric] for p in rows.values() if metric in p.get(method, {})]
        out[metric] = {
            "n": len(values),
            "mean": float(np.mean(values)) if values else None,
            "std": float(np.std(values, ddof=1)) if len(values) > 1 else None,
        }
    return out


def _paired(
    rows: dict[str, dict[str, dict[str, float]]], a: str, b: str, metric: str
) -> dict[str, Any]:
    pairs = [
        (p[a][metric], p[b][metric])
        for p in rows.values()
        if metric in p.get(a, {}) and metric in p.get(b, {})
    ]
    result: dict[str, Any] = {"metric": metric, "a": a, "b": b, "n": len(pairs)}
    if len(pairs) < 2:
        result.update(t=None, p=None, note="needs 2 participants with both")
        return result
    first, second = np.array(pairs).T
    if np.allclose(first - second, (first - second)[0]):
        result.update(t=None, p=None, note="differences are constant")
        return result
    test = stats.ttest_rel(first, second)
    result.update(
        t=float(test.statistic),
        p=float(test.pvalue),
        mean_difference=float(np.mean(first - second)),
    )
    return result


def _cell(stat: dict[str, Any], digits: int) -> str:
    if stat["mean"] is None:
        return "-"
    std = "" if stat["std"] is None else f" ± {stat['std']:.{digits}f}"
    return f"{stat['mean']:.{digits}f}{std} (n={stat['n']})"


def format_report(report: dict[str, Any]) -> str:
    lines = [
        f"# Study report: {len(report['participants'])} participant(s)",
        "",
        "| method | satisfaction (1-5) | final eval return | mean latency (ms) | time-outs |",
        "|---|---|---|---|---|",
    ]
    for method, stat in report["methods"].items():
        lines.append(
            f"| {method} | {_cell(stat['satisfaction'], 2)} | {_cell(stat['reward'], 1)} | "
            f"{_cell(stat['latency_ms'], 0)} | {_cell(stat['timeouts'], 1)} |"
        )
    lines += [
        "",
        "Paired-sample t-tests (two-sided):",
        "",
        "| metric | methods | n | t | p |",
        "|---|---|---|---|---|",
    ]
    for test in report["tests"]:
        if test["t"] is None:
            t, p = "-", test["note"]
        else:
            t, p = f"{test['t']:.3f}", f"{test['p']:.4f}"
        lines.append(f"| {test['metric']} | {test['a']} vs {test['b']} | {test['n']} | {t} | {p} |")
    return "\n".join(lines) + "\n"
