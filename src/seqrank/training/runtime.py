"""Where and how a run computes: device, path and precision, with every "auto" resolved
here and nowhere else.

`auto` device: CUDA when there is one. `auto` path: the fast path on CUDA for SAC tasks;
on a CPU the fast path in bf16 where `cpu_path` finds it measured faster at the run's
shapes and checked to learn the same, the reference path elsewhere. `auto` precision:
TF32 for the fast path on CUDA, bf16 for the fast path that `--path auto` chose on a CPU,
fp32 everywhere else.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from seqrank.choices import (
    Device,
    Precision,
    TrainingPath,
    check_path,
    fast_path_needed,
    parse_choice,
)
from seqrank.config import TrainConfig
from seqrank.envs import canonical_task
from seqrank.errors import SettingError, setting
from seqrank.training.cpu_path import UpdateShape, auto_cpu_precision

DEVICES = tuple(Device)
PATHS = tuple(TrainingPath)
PRECISIONS = tuple(Precision)


@dataclass(frozen=True)
class Runtime:
    device: torch.device
    fast: bool  # the fast path: buffer on the device, stacked critics, fused Adam, graphs
    precision: str  # fp32, tf32 or bf16

    @property
    def path(self) -> str:
        return "fast" if self.fast else "reference"


def resolve_device(name: str) -> torch.device:
    name = parse_choice(Device, name, "device")
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise SettingError(
            f"{setting('device')} 'cuda' requested but no CUDA device is available; use cpu or auto"
        )
    return torch.device(name)


def resolve_runtime(
    device: str | torch.device,
    path: str,
    precision: str,
    discrete: bool,
    shape: UpdateShape | None = None,
) -> Runtime:
    """The run's device, path and precision; ValueError for a combination that does not
    exist (a precision the path lacks, the fast path for a discrete task). With the run's
    `shape`, `auto` on a CPU may choose the fast path in bf16 (`cpu_path`)."""
    where = device if isinstance(device, torch.device) else resolve_device(device)
    path = parse_choice(TrainingPath, path, "path")
    precision = parse_choice(Precision, precision, "precision")
    check_path(path, precision, discrete)
    chosen = _auto_cpu_precision(where, path, precision, discrete, shape)
    if chosen is not None:
        return Runtime(where, True, chosen)
    fast = (where.type == "cuda" and not discrete) if path == "auto" else path == "fast"
    if not fast and precision not in ("auto", "fp32"):
        raise fast_path_needed(precision, discrete)
    if precision == "auto":
        precision = "tf32" if fast and where.type == "cuda" else "fp32"
    return Runtime(where, fast, precision)


def _auto_cpu_precision(
    where: torch.device, path: str, precision: str, discrete: bool, shape: UpdateShape | None
) -> str | None:
    """On a CPU, `--path auto --precision auto` may take the flat update (`cpu_path`)."""
    if where.type != "cpu" or path != "auto" or precision != "auto" or discrete or not shape:
        return None
    return auto_cpu_precision(shape)


def config_runtime(config: TrainConfig, device: str | torch.device) -> Runtime:
    """`resolve_runtime` for a run config (block:place learns with DQN: discrete)."""
    discrete = canonical_task(config.task)[0] == "block"
    return resolve_runtime(device, config.path, config.precision, discrete)
