"""Read every run directory under a folder: settings, final scores, curves, feedback rows.

Finished runs (with `summary.json`) and unfinished ones (metrics so far) are both read; an
unfinished run reports its last evaluation (the report leaves it out unless asked). Each
task's metric (`envs/scoring.py`) is decided once, from all its runs, so that every method
of a task is scored alike.
"""

from __future__ import annotations

import json
from collections import defaultdict
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from seqrank.envs.scoring import Metric, normalizing_scale, task_metric
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
    metric: Metric = Metric.RETURN  # its task's, set by `collect_runs`

    @property
    def baseline(self) -> bool:
        return self.reward != "learned"

    @property
    def score(self) -> float | None:
        return self.final_success if self.metric is Metric.SUCCESS else self.final_return

    @property
    def normalized(self) -> float | None:
        """On a 0-1 scale across tasks (success / 100, DMControl return / 1000); None for a
        return whose range is not known."""
        scale = normalizing_scale(self.task, self.metric)
        return None if self.score is None or scale is None else self.score / scale


def _offline_task(directory: Path, config: dict[str, Any]) -> str | None:
    """The task of an offline run made without `--task` (its config records null): the
    one its summary names, else the one its dataset records; None when neither can say."""
    summary = directory / "summary.json"
    if summary.is_file():
        task = json.loads(summary.read_text()).get("task")
        if task:
            return str(task)
    if not config.get("dataset"):
        return None
    from seqrank.offline.minari_io import dataset_task, read_metadata

    try:
        return dataset_task(read_metadata(config["dataset"])[1])
    except (OSError, ValueError):
        return None


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
        task = config["task"] or _offline_task(directory, config)
        if task is None:
            continue  # an offline run whose dataset is gone and that never finished
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
                task,
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
    return with_task_metrics(results)


def with_task_metrics(runs: list[RunResult]) -> list[RunResult]:
    """The runs, each with its task's metric, decided from every run of that task."""
    rates: dict[str, list[float]] = defaultdict(list)
    for run in runs:
        rates[run.task] += [success for _, _, success in run.curve]
    metrics = {task: task_metric(task, values) for task, values in rates.items()}
    return [replace(run, metric=metrics[run.task]) for run in runs]
