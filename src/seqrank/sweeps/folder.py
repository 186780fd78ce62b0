"""A sweep's folder as it is on disk, against the sweep's plan: runs made with other
settings (`changed_runs`), set aside before they are run again (`set_aside`).

A saved run that differs from the planned one only in settings that never reach it (a
baseline's `spec.unused_settings`) is the planned run: it is neither changed nor run again,
and it continues with its saved settings (`as_saved`). A baseline that earlier versions
planned under a variant's name (`PlannedRun.former`) is taken over from that directory
(`earlier_runs`, `take_over`), a finished one first.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from seqrank.sweeps.spec import PlannedRun, Sweep, unused_settings

if TYPE_CHECKING:
    from seqrank.config import TrainConfig


def _saved(path: Path) -> TrainConfig | None:
    from seqrank.training.runs import RunDir

    return RunDir.open(path).read_config() if (path / "config.json").is_file() else None


def differences(saved: TrainConfig, planned: TrainConfig) -> list[str]:
    """The settings that differ and reach the planned run, as `name saved -> planned`."""
    from seqrank.config import config_differences

    ignored = {name: getattr(planned, name) for name in unused_settings(planned)}
    return config_differences(replace(saved, **ignored), planned)


def earlier_runs(sweep: Sweep) -> dict[str, str]:
    """Planned runs without a directory whose run an earlier version made under another
    name, with settings that differ only where they never reach it: planned -> that name."""
    found = {}
    for planned in sweep.runs:
        if planned.former and not (sweep.out / "runs" / planned.name).exists():
            earlier = _earlier_run(sweep.out / "runs", planned)
            if earlier is not None:
                found[planned.name] = earlier
    return found


def _earlier_run(runs: Path, planned: PlannedRun) -> str | None:
    alike = [
        name
        for name in planned.former
        if (saved := _saved(runs / name)) is not None and not differences(saved, planned.config)
    ]
    finished = [name for name in alike if (runs / name / "summary.json").is_file()]
    return next(iter(finished + alike), None)


def take_over(sweep: Sweep, earlier: dict[str, str]) -> None:
    """Rename each earlier run's directory to its planned name, holding its lock."""
    from seqrank.dirs import DirLock

    for name, old in earlier.items():
        source = sweep.out / "runs" / old
        with DirLock(source, "run directory"):
            source.rename(sweep.out / "runs" / name)


def as_saved(sweep: Sweep) -> Sweep:
    """The sweep with each run that exists already under its saved settings (which differ
    from the planned ones, if at all, only where they never reach it)."""
    runs = []
    for planned in sweep.runs:
        saved = _saved(sweep.out / "runs" / planned.name)
        runs.append(planned if saved is None else replace(planned, config=saved))
    return replace(sweep, runs=tuple(runs))


def changed_runs(sweep: Sweep) -> list[tuple[str, list[str]]]:
    """Runs whose directory holds a run of other settings than the sweep now plans, with
    what differs (saved -> planned)."""
    changed = []
    for planned in sweep.runs:
        saved = _saved(sweep.out / "runs" / planned.name)
        if saved is not None and (differ := differences(saved, planned.config)):
            changed.append((planned.name, differ))
    return changed


def set_aside(sweep: Sweep, names: list[str]) -> Path:
    """Move the named runs' directories to `<out>/replaced/<time>/`, each while holding
    its lock (a run that is training elsewhere is not moved); returns that folder."""
    from seqrank.dirs import DirLock

    folder = sweep.out / "replaced" / time.strftime("%Y%m%d-%H%M%S")
    for name in names:
        source, target = sweep.out / "runs" / name, folder / name
        with DirLock(source, "run directory"):
            target.parent.mkdir(parents=True, exist_ok=True)
            source.rename(target)
    return folder
