"""Window-open's runs set beside the paper's row (issue 46, item 1): a markdown table from
`seqrank report`'s report.json.

    seqrank report results/online-window-open-cpu/runs --out results/online-window-open-cpu
    python scripts/window_open_vs_paper.py results/online-window-open-cpu/report.json

Each scheme's row: the paper's supplementary Table 7 (PEBBLE, window-open v2, 1,000
questions, 1M steps, success rate over 5 seeds, mean ± std), this folder's final success
rate (mean ± sample std, seeds), its IQM with the report's 95% bootstrap interval, and the
probability that the scheme beats pairwise (P(X > pairwise)) with its interval. Then the
paper's order, root > sequential > pairwise, checked on the IQMs and on the probabilities
of improvement (an order is shown only where the interval lies above 1/2).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

TASK = "window-open"
# supplementary Table 7, window-open row: mean and std of success (%) over 5 seeds
PAPER = {"pairwise": (49.4, 43.2), "sequential": (72.4, 39.0), "root": (98.6, 3.1)}
ORDER = ("pairwise", "sequential", "root", "ranked", "true-reward")


def comparison(report: dict[str, Any]) -> list[str]:
    cells = {c["method"]: c for c in report["table"] if c["task"] == TASK}
    if not cells:
        raise SystemExit(f"the report holds no {TASK} runs (its tasks: {report['tasks']})")
    beats = {p["x"]: p for p in report["probability_of_improvement"] if p["y"] == "pairwise"}
    lines = [
        "| method | paper (Table 7, 5 seeds, 1M steps) | here: final success | IQM [95% CI] "
        "| P(X > pairwise) [95% CI] |",
        "|---|---|---|---|---|",
    ]
    for method in [m for m in ORDER if m in cells] + sorted(set(cells) - set(ORDER)):
        cell = cells[method]
        paper = f"{PAPER[method][0]:.1f} ± {PAPER[method][1]:.1f}" if method in PAPER else "-"
        ours = f"{cell['mean']:.1f} ± {cell['std']:.1f} ({cell['n']} seeds)"
        iqm = f"{cell['iqm']:.1f} [{cell['iqm_low']:.1f}, {cell['iqm_high']:.1f}]"
        better = beats.get(method)
        odds = f"{better['p']:.2f} [{better['low']:.2f}, {better['high']:.2f}]" if better else "-"
        lines.append(f"| {method} | {paper} | {ours} | {iqm} | {odds} |")
    return [*lines, "", _order_line(cells, report["probability_of_improvement"])]


def _order_line(cells: dict[str, Any], improvements: list[dict[str, Any]]) -> str:
    schemes = [s for s in PAPER if s in cells]
    by_iqm = " > ".join(sorted(schemes, key=lambda s: -cells[s]["iqm"]))
    shown = [
        f"{p['x']} over {p['y']}"
        for p in improvements
        if p["x"] in schemes and p["y"] in schemes and p["low"] > 0.5
    ]
    return (
        f"The paper's order: root > sequential > pairwise. Here, by IQM: {by_iqm}; "
        "shown by a probability of improvement whose interval lies above 1/2: "
        + (", ".join(shown) if shown else "none")
        + "."
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", type=Path, help="report.json of `seqrank report`")
    args = parser.parse_args(argv)
    if not args.report.is_file():
        raise SystemExit(f"{args.report} is not a file: run `seqrank report` first")
    print("\n".join(comparison(json.loads(args.report.read_text()))))


if __name__ == "__main__":
    main()
