"""Read every run directory under a folder: settings, final scores, curves, feedback rows.

Finished runs (with `summary.json`) and unfinished ones (metrics so far) are both read; an
unfinished run reports its last evaluation and is marked partial.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from seqrank.envs import canonical_task
from seqrank.rows import read_rows


@dataclass(frozen=True)
class RunResult:
    path: Path
    task: str
    scheme: str
    backbone: str
    teacher: str
    reward: str  # learned, or a baseline: true, none
    seed: int
    scale: str
    finished: bool
    steps: int  # of the last evaluation
    total_steps: int
    final_return: float | None
    final_success: float | None  # percent
    curve: tuple[tuple[int, float, float], ...]  # (step, return, success %)
    feedback: tuple[dict[str, Any], ...]
    settings: dict[str, Any] = field(default_factory=dict, compare=False)  # its config.json

    @property
    def baseline(self) -> bool:
        return self.reward != "learned"

    @property
    def suite(self) -> str:
        return canonical_task(self.task)[0]

    @property
    def metric(self) -> str:
        """What the paper reports: return on DMControl, success rate on manipulation."""
        return "return" if self.suite == "dmc" else "success"

    @property
    def score(self) -> float | None:
        return self.final_return if self.metric == "return" else self.final_success

    @property
    def normalized(self) -> float | None:
        """On a 0-1 scale across suites: DMControl returns / 1000, success rates / 100."""
        score = self.score
        if score is None:
            return None
        return score / 1000.0 if self.metric == "return" else score / 100.0


def collect_runs(folder: Path) -> list[RunResult]:
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"{folder} is not a folder")
    results = []
    for config_path in sorted(folder.rglob("config.json")):
        directory = config_path.parent
        try:
            config = json.loads(config_path.read_text())
        except json.JSONDecodeError:
            continue  # not a run directory of ours (or a broken one): nothing to report
        if "scheme" not in config or "task" not in config:
            continue
        rows = read_rows(directory / "metrics.jsonl")
        evals = [r for r in rows if r.get("kind") == "eval"]
        curve = tuple(
            (int(r["step"]), float(r["eval_return"]), float(r.get("eval_success_rate", 0.0)))
            for r in evals
        )
        last = evals[-1] if evals else None
        results.append(
            RunResult(
                directory,
                config["task"],
                config["scheme"],
                config.get("backbone", "pebble"),
                config.get("teacher", "oracle"),
                str(config.get("reward", "learned")),
                int(config.get("seed", 0)),
                str(config.get("scale", "paper")),
                (directory / "summary.json").exists(),
                int(last["step"]) if last else 0,
                int(config.get("steps", 0)),
                float(last["eval_return"]) if last else None,
                float(last.get("eval_success_rate", 0.0)) if last else None,
                curve,
                tuple(r for r in rows if r.get("kind") == "feedback"),
                config,
            )
        )
    if not results:
        raise ValueError(f"{folder} holds no run directories (no config.json of a seqrank run)")
    return results
