"""Each run's evaluation success rate at every step, one markdown row a run.

For a sweep's runs folder (`seqrank sweep`'s `runs/`, or its copy in `results/`): the
success rate (%) of each evaluation, the run's wall time and its inferred labels (wrong).
A resumed run repeats its last evaluation row; the last row of a step counts.

    python scripts/success_by_step.py results/online-window-open-cpu/runs
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def evaluations(metrics: Path) -> dict[int, float]:
    """Success rate (%) by step, the last row of a step winning."""
    rates: dict[int, float] = {}
    for line in metrics.read_text().splitlines():
        row = json.loads(line)
        if row.get("kind") == "eval":
            rates[int(row["step"])] = float(row.get("eval_success_rate", 0.0))
    return rates


def run_label(run: Path) -> str:
    name = run.name.replace("_pebble_oracle", "").replace("_seed", ", seed ")
    return name.replace("true-reward", "true reward")


def table(runs: Path) -> list[str]:
    folders = sorted(p.parent for p in runs.rglob("metrics.jsonl"))
    steps = sorted({step for f in folders for step in evaluations(f / "metrics.jsonl")})
    header = ["run", *(f"{step // 1000}K" for step in steps), "wall (min)", "inferred (wrong)"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for folder in folders:
        rates = evaluations(folder / "metrics.jsonl")
        summary_file = folder / "summary.json"
        summary = json.loads(summary_file.read_text()) if summary_file.exists() else {}
        wall = f"{summary['wall_seconds'] / 60:.1f}" if "wall_seconds" in summary else "running"
        inferred = summary.get("inferred", 0)
        wrong = f" ({summary['inferred_wrong']})" if inferred else ""
        cells = [f"{rates[s]:.0f}" if s in rates else "" for s in steps]
        lines.append(
            "| " + " | ".join([run_label(folder), *cells, wall, f"{inferred}{wrong}"]) + " |"
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, help="a sweep's runs folder")
    print("\n".join(table(parser.parse_args().runs)))


if __name__ == "__main__":
    main()
