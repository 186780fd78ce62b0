"""A self-describing run directory.

config.json      the full resolved TrainConfig (an offline run's: its OfflineConfig)
meta.json        seed, device, package versions, git revision, command, start time
metrics.jsonl    one JSON object per line, each with `step` and `kind`
                 (`eval`, `feedback`, `train`); keys in docs/reference/metrics.md
checkpoint.pt    the latest checkpoint (written atomically at an episode end)
summary.json     final numbers (a run with it is finished); returns.png the evaluation curve
events.out.tfevents.*  the same metrics for TensorBoard; wandb.json with `--wandb`
.lock            held by the one process that trains it (`seqrank.dirs.DirLock`)
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
from typing import Any, Protocol

import torch

from seqrank.config import TrainConfig
from seqrank.dirs import LOCK_NAME, DirLock, check_folder, missing_folders, remove_made
from seqrank.training.cpu_path import processor
from seqrank.training.sinks import MetricSink, TensorBoardSink, WandbSink


class RunSettings(Protocol):
    """What a run directory records of a run's settings: an online run's `TrainConfig`,
    an offline run's `offline.settings.OfflineConfig`."""

    @property
    def seed(self) -> int: ...

    def as_dict(self) -> dict[str, Any]: ...


PACKAGES = ("seqrank", "torch", "numpy", "mujoco", "dm-control", "metaworld", "gymnasium")


class RunDir:
    def __init__(self, path: Path):
        self.path = path
        self._sinks: list[MetricSink] | None = None  # opened at the first row
        self._purge_step: int | None = None
        self._lock = DirLock(path, "run directory")
        self._made: list[Path] = []  # folders `create` made, removed again by `discard`

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
        cls, path: Path, config: RunSettings, device: str, wandb: str | None = None
    ) -> RunDir:
        """A new run directory, locked by this process; `wandb` names a W&B project that
        also gets the metrics (kept in meta.json, so a resumed run logs there too)."""
        path = Path(path)
        cls.check_new(path)
        made = missing_folders(path)
        path.mkdir(parents=True, exist_ok=True)
        run = cls(path)
        run._made = made
        try:
            run.lock()
        except ValueError:
            remove_made(made)
            raise
        _write_json(run.config_path, config.as_dict())
        _write_json(path / "meta.json", {**_meta(config, device), "wandb": wandb})
        run.metrics_path.touch()
        return run

    @staticmethod
    def check_new(path: Path) -> None:
        """ValueError or FileExistsError unless a new run can be made at `path` (nothing
        is written)."""
        check_folder(path, "run directory")
        if path.exists() and any(p.name != LOCK_NAME for p in path.iterdir()):
            raise FileExistsError(
                f"run directory {path} is not empty; resume it with --resume {path} "
                "or choose another --out"
            )

    @classmethod
    def open(cls, path: Path) -> RunDir:
        run = cls(Path(path))
        if not run.config_path.is_file():
            raise FileNotFoundError(f"no run directory at {path} (config.json missing)")
        return run

    def lock(self) -> None:
        """Hold the directory for this process (DirectoryInUse when another holds it)."""
        self._lock.acquire()

    def release(self) -> None:
        self._lock.release()

    def discard(self) -> None:
        """Undo `create` after a failed start: remove everything in the directory (it was
        new or empty) and the folders it made, so the same command can run again."""
        import shutil

        self.close_sinks()
        for child in self.path.iterdir():
            if child.is_dir() and not child.is_symlink():
                shutil.rmtree(child, ignore_errors=True)
            else:
                child.unlink(missing_ok=True)
        self.release()
        remove_made(self._made)

    def discard_interrupted(self, when: str, lost: str = "") -> str:
        """`discard` after a second Ctrl-C (or SIGTERM) before training began, when there is
        nothing to resume yet; the line that says so (`when`: what the start was doing;
        `lost`: what else went with the directory)."""
        self.discard()
        kept = " (the empty folder given is kept)" if self.path.exists() else ""
        return f"interrupted {when}, before training began: removed {self.path}{kept}{lost}"

    @property
    def finished(self) -> bool:
        return (self.path / "summary.json").is_file()

    def read_config(self) -> TrainConfig:
        try:
            values = json.loads(self.config_path.read_text())
        except json.JSONDecodeError:
            raise ValueError(f"{self.config_path} is not a run's config (not JSON)") from None
        if not isinstance(values, dict):
            raise ValueError(f"{self.config_path} is not a run's config (not a JSON object)")
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
        try:
            state: dict[str, Any] = torch.load(self.checkpoint_path, weights_only=False)
        except Exception as error:  # a file that is not a checkpoint of ours
            raise ValueError(
                f"{self.checkpoint_path} is not a readable checkpoint ({type(error).__name__}); "
                "move it away to start the run over"
            ) from None
        return state

    def read_summary(self) -> dict[str, Any]:
        result: dict[str, Any] = json.loads((self.path / "summary.json").read_text())
        return result

    def write_summary(self, summary: dict[str, Any]) -> None:
        _write_json(self.path / "summary.json", summary)


def _write_json(path: Path, value: Any) -> None:
    path.write_text(json.dumps(value, indent=2) + "\n")


def _meta(config: RunSettings, device: str) -> dict[str, Any]:
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
        "cpu": processor(),
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
