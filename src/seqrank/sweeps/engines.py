"""Running a sweep: each run in its own process (local pool or Ray), with retries.

A finished run (its `summary.json` exists) is skipped; a killed run resumes from its last
checkpoint; a failed run is tried again `retries` times and then reported, never dropped.
`<out>/sweep.json` records every run's state after each event, atomically.

Stopping: local workers ignore SIGINT and take SIGTERM as "stop at the next episode end with
a checkpoint, and start no other run"; the sweep command forwards its own SIGINT or SIGTERM
to them (`LocalBackend.stop`), so a signal sent to the sweep's process alone, as `kill` and
schedulers do, stops every run cleanly. A second signal stops them at once.
"""

from __future__ import annotations

import contextlib
import json
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from seqrank.sweeps.spec import PlannedRun, Sweep

ENGINES = ("local", "ray")

# set in a local worker process by its first SIGTERM (see `_start_worker`)
_worker_stop: threading.Event | None = None


def _start_worker() -> None:
    """A local worker's signals: SIGINT is the sweep command's to handle (a terminal's
    Ctrl-C reaches the whole process group); the first SIGTERM asks the run to stop, a
    second one interrupts it."""
    from seqrank.training.stopping import stop_then_interrupt

    global _worker_stop
    stop = _worker_stop = threading.Event()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, stop_then_interrupt(lambda signum: stop.set()))


def failure_text(error: BaseException) -> str:
    """How a failed run's error is recorded (`sweep.json`, the summary), the same for every
    engine: its type's name and its first line."""
    first = (str(error).splitlines() or [""])[0]
    return f"{type(error).__name__}: {first}" if first else type(error).__name__


def train_run(
    path: str, config: dict[str, Any], threads: int, wandb: str | None = None
) -> dict[str, Any]:
    """Train (or finish, or skip) one run; runs inside a worker process. The run's directory
    is locked while it trains; Ctrl-C or SIGTERM stop it at its next episode end, with a
    checkpoint."""
    import torch

    from seqrank.config import TrainConfig
    from seqrank.training.launch import open_or_start
    from seqrank.training.stopping import stop_on_signals
    from seqrank.training.trainer import Trainer

    if _worker_stop is not None and _worker_stop.is_set():
        raise RuntimeError("the sweep is stopping: run not started")
    torch.set_num_threads(threads)
    settings = TrainConfig(**config)
    started = open_or_start(Path(path), settings, settings.device, Trainer, wandb)
    try:
        if started.finished:
            return {"status": "skipped", "summary": started.run.read_summary()}
        if _worker_stop is not None:  # a local worker: its SIGTERM handler is installed
            started.trainer.stop_requested = _worker_stop
            summary = started.trainer.train()
        else:
            with stop_on_signals(started.trainer.stop_requested.set, lambda text: None):
                summary = started.trainer.train()
        return {"status": "resumed" if started.resumed else "trained", "summary": summary}
    finally:
        started.run.release()


def changed_runs(sweep: Sweep) -> list[tuple[str, list[str]]]:
    """Runs whose directory holds a run of other settings than the sweep now plans, with
    what differs (saved -> planned)."""
    from seqrank.config import config_differences
    from seqrank.training.runs import RunDir

    changed = []
    for planned in sweep.runs:
        path = sweep.out / "runs" / planned.name
        if (path / "config.json").is_file():
            differences = config_differences(RunDir.open(path).read_config(), planned.config)
            if differences:
                changed.append((planned.name, differences))
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


@dataclass
class RunState:
    name: str
    state: str = "pending"  # pending | running | trained | resumed | skipped | failed
    attempts: int = 0
    error: str | None = None
    final_eval_return: float | None = None


@dataclass
class SweepStatus:
    runs: dict[str, RunState] = field(default_factory=dict)

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for run in self.runs.values():
            out[run.state] = out.get(run.state, 0) + 1
        return out


Event = Callable[[SweepStatus, RunState], None]


class Backend(Protocol):
    def submit(self, run: PlannedRun, path: Path) -> Any: ...
    def done(self) -> Iterator[tuple[Any, dict[str, Any] | None, str | None]]: ...
    def stop(self) -> None: ...
    def close(self) -> None: ...


class LocalBackend:
    """A process pool (spawned processes: no GL or torch state shared), one thread per run."""

    def __init__(self, workers: int):
        context = multiprocessing.get_context("spawn")
        self.pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_start_worker)
        self.pending: set[Future[dict[str, Any]]] = set()

    def submit(self, run: PlannedRun, path: Path) -> Any:
        future = self.pool.submit(train_run, str(path), run.config.as_dict(), 1, run.wandb)
        self.pending.add(future)
        return future

    def done(self) -> Iterator[tuple[Any, dict[str, Any] | None, str | None]]:
        finished, self.pending = wait(self.pending, return_when=FIRST_COMPLETED)
        for future in finished:
            error = future.exception()
            if error is None:
                yield future, future.result(), None
            else:
                yield future, None, failure_text(error)

    def stop(self) -> None:
        """SIGTERM to every worker: each run stops at its next episode end with a checkpoint
        (a second call stops them at once); `close` then waits for them."""
        # the executor keeps its worker processes only in a private field
        for process in list(getattr(self.pool, "_processes", {}).values()):
            with contextlib.suppress(ProcessLookupError):
                os.kill(process.pid, signal.SIGTERM)

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


class RayBackend:
    """Ray tasks with per-run CPU and GPU fractions (several runs can share one GPU)."""

    def __init__(
        self, address: str | None, workers: int, cpus: float, gpus: float, temp: Path | None
    ):
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        import ray

        self.ray = ray
        options: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address is None:
            options["num_cpus"] = workers
            if temp is not None:
                options["_temp_dir"] = str(temp)
        ray.init(address=address, **options)
        self.task = ray.remote(num_cpus=cpus, num_gpus=gpus, max_retries=0)(train_run)
        self.pending: list[Any] = []

    def submit(self, run: PlannedRun, path: Path) -> Any:
        ref = self.task.remote(str(path.resolve()), run.config.as_dict(), 1, run.wandb)
        self.pending.append(ref)
        return ref

    def done(self) -> Iterator[tuple[Any, dict[str, Any] | None, str | None]]:
        ready, self.pending = self.ray.wait(self.pending, num_returns=1)
        for ref in ready:
            try:
                yield ref, self.ray.get(ref), None
            except self.ray.exceptions.RayError as error:
                cause = getattr(error, "cause", None) or error
                yield ref, None, failure_text(cause)

    def stop(self) -> None:
        """Nothing to send: `close` shuts Ray down, which ends its workers; their runs
        continue from their last checkpoint."""

    def close(self) -> None:
        self.ray.shutdown()


def run_sweep(sweep: Sweep, backend: Backend, on_event: Event | None = None) -> SweepStatus:
    """Run every planned run to completion or failure; returns the final status."""
    runs_dir = sweep.out / "runs"
    status = SweepStatus({r.name: RunState(r.name) for r in sweep.runs})
    by_handle: dict[Any, PlannedRun] = {}

    def start(run: PlannedRun) -> None:
        state = status.runs[run.name]
        state.state, state.attempts = "running", state.attempts + 1
        by_handle[backend.submit(run, runs_dir / run.name)] = run

    try:
        for run in sweep.runs:
            start(run)
        _save(sweep, status)
        while by_handle:
            for handle, result, error in backend.done():
                run = by_handle.pop(handle)
                state = status.runs[run.name]
                if error is None and result is not None:
                    state.state, state.error = result["status"], None
                    state.final_eval_return = result["summary"].get("final_eval_return")
                elif state.attempts <= sweep.retries:
                    state.error = error
                    start(run)
                else:
                    state.state, state.error = "failed", error
                _save(sweep, status)
                if on_event is not None:
                    on_event(status, state)
    finally:
        backend.close()
    return status


def _save(sweep: Sweep, status: SweepStatus) -> None:
    sweep.out.mkdir(parents=True, exist_ok=True)
    payload = {
        "name": sweep.name,
        "updated": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "counts": status.counts(),
        "runs": [vars(r) for r in status.runs.values()],
    }
    partial = sweep.out / "sweep.json.part"
    partial.write_text(json.dumps(payload, indent=2))
    partial.replace(sweep.out / "sweep.json")
