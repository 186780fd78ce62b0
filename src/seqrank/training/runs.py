"""A self-describing run directory.

config.json      the full resolved TrainConfig
meta.json        seed, device, package versions, git revision, command, start time
metrics.jsonl    one JSON object per line, each with `step` and `kind`
                 (`eval`, `feedback`, `train`); keys documented in the README
checkpoint.pt    the latest checkpoint (written atomically at an episode end)
summary.json     final numbers; returns.png the evaluation curve
events.out.tfevents.*  the same metrics for TensorBoard; wandb.json with `--wandb`
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from dataclasses import fields
from importlib import metadata
from pathlib import Path
from typing import Any

import torch

from seqrank.config import TrainConfig
from seqrank.training.sinks import MetricSink, TensorBoardSink, WandbSink

PACKAGES = ("seqrank", "torch", "numpy", "mujoco", "dm-control", "metaworld", "gymnasium")


class RunDir:
    def __init__(self, path: Path):
        self.path = path
        self._sinks: list[MetricSink] | None = None  # opened at the first row
        self._purge_step: int | None = None

    @property
    def wandb_project(self) -> str | None:
        meta = self.path / "meta.json"
        return json.loads(meta.read_text()).get("wandb") if meta.exists() else None

    @property
    def config_path(self) -> Path:
        return self.path / "config.json"

    @property
    def metrics_path(self) -> Path:
        return self.path / "metrics.jsonl"

    @property
    def checkpoint_path(self) -> Path:
        return self.path / "checkpoint.pt"

    @classmethod
    def create(
        cls, path: Path, config: TrainConfig, device: str, wandb: str | None = None
    ) -> RunDir:
        """A new run directory; `wandb` names a W&B project that also gets the metrics
        (kept in meta.json, so a resumed run logs there too)."""
        if path.exists() and any(path.iterdir()):
            raise FileExistsError(
                f"run directory {path} is not empty; resume it with --resume {path} "
                "or choose another --out"
            )
        path.mkdir(parents=True, exist_ok=True)
        run = cls(path)
        _write_json(run.config_path, config.as_dict())
        _write_json(path / "meta.json", {**_meta(config, device), "wandb": wandb})
        run.metrics_path.touch()
        return run

    @classmethod
    def open(cls, path: Path) -> RunDir:
        run = cls(path)
        if not run.config_path.is_file():
            raise FileNotFoundError(f"no run directory at {path} (config.json missing)")
        return run

    def read_config(self) -> TrainConfig:
        values = json.loads(self.config_path.read_text())
        known = {f.name for f in fields(TrainConfig)}
        return TrainConfig(**{k: v for k, v in values.items() if k in known})

    def append_metrics(self, row: dict[str, Any]) -> None:
        with self.metrics_path.open("a") as handle:
            handle.write(json.dumps(row) + "\n")
        for sink in self._open_sinks():
            sink.write(row)

    def _open_sinks(self) -> list[MetricSink]:
        if self._sinks is None:
            self._sinks = [TensorBoardSink(self.path, self._purge_step)]
            project = self.wandb_project
            if project:
                self._sinks.append(WandbSink(project, self.path, self.read_config().as_dict()))
        return self._sinks

    def close_sinks(self) -> None:
        for sink in self._sinks or []:
            sink.close()
        self._sinks = None

    def read_metrics(self) -> list[dict[str, Any]]:
        if not self.metrics_path.exists():
            return []
        lines = self.metrics_path.read_text().splitlines()
        return [json.loads(line) for line in lines if line.strip()]

    def truncate_metrics(self, step: int, rows: int | None = None) -> None:
        """Drop rows written after the checkpoint at `step` (they will be written again):
        rows of later steps, and beyond the first `rows` rows when the checkpoint counted
        them (an evaluation finished in the background is logged after its step)."""
        kept = [row for row in self.read_metrics()[:rows] if row["step"] <= step]
        self._purge_step = step + 1  # TensorBoard drops its events after the checkpoint too
        tmp = self.metrics_path.with_suffix(".tmp")
        tmp.write_text("".join(json.dumps(row) + "\n" for row in kept))
        os.replace(tmp, self.metrics_path)

    def save_checkpoint(self, state: dict[str, Any]) -> None:
        tmp = self.checkpoint_path.with_suffix(".tmp")
        torch.save(state, tmp)
        os.replace(tmp, self.checkpoint_path)  # a kill never leaves half a checkpoint

    def load_checkpoint(self) -> dict[str, Any] | None:
        if not self.checkpoint_path.exists():
            return None
        state: dict[str, Any] = torch.load(self.checkpoint_path, weights_only=False)
        return state

    def read_summary(self) -> dict[str, Any]:
        result: dict[str, Any] = json.loads((self.path / "summary.json").read_text())
        return result

    def write_summary(self, summary: dict[str, Any]) -> None:
        _write_json(self.path / "summary.json", summary)


def _write_json(path: Path, value: Any) -> None:
    path.write_text(json.dumps(value, indent=2) + "\n")


def _meta(config: TrainConfig, device: str) -> dict[str, Any]:
    versions: dict[str, str | None] = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return {
        "seed": config.seed,
        "device": device,
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "command": sys.argv,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "packages": versions,
        "git_revision": _git_revision(),
    }


def _git_revision() -> str | None:
    try:
        result = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=5,
            cwd=Path(__file__).resolve().parent,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return result.stdout.strip() or None if result.returncode == 0 else None
