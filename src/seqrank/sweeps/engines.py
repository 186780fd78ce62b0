"""The engines that run a sweep's runs, each in its own process: a local pool or Ray.

A finished run (its `summary.json` exists) is skipped; a killed run resumes from its last
checkpoint. Each run says when it has begun (it holds its directory's lock) through a queue
(`Backend.started`), so the sweep can tell queued runs from running ones, and each run's
end says whether it finished, failed, or was stopped on request (`Ended`).

Stopping: local workers ignore SIGINT and take SIGTERM as "stop at the next episode end with
a checkpoint, and start no other run"; the sweep forwards each SIGINT or SIGTERM it gets to
them (`LocalBackend.stop`), so a signal sent to the sweep's process alone, as `kill` and
schedulers do, stops every run cleanly. A second signal stops them at once. Ray's tasks are
cancelled instead (`RayBackend.stop`): they continue later from their last checkpoint.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from seqrank.sweeps.spec import PlannedRun

ENGINES = ("local", "ray")

# set in a local worker process by its first SIGTERM (see `_start_worker`)
_worker_stop: threading.Event | None = None
# where a local worker says that a run has begun (see `_start_worker`)
_worker_starts: Any = None


class NotStarted(Exception):
    """The sweep was stopping when a worker took this run: it did not begin."""


def _start_worker(starts: Any) -> None:
    """A local worker's signals: SIGINT is the sweep command's to handle (a terminal's
    Ctrl-C reaches the whole process group); the first SIGTERM asks the run to stop, a
    second one interrupts it. `starts` is the queue its runs announce their start on."""
    from seqrank.training.stopping import stop_then_interrupt

    global _worker_stop, _worker_starts
    stop = _worker_stop = threading.Event()
    _worker_starts = starts
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, stop_then_interrupt(lambda signum: stop.set()))


def failure_text(error: BaseException) -> str:
    """How a failed run's error is recorded (`sweep.json`, the summary), the same for every
    engine: its type's name and its first line."""
    first = (str(error).splitlines() or [""])[0]
    return f"{type(error).__name__}: {first}" if first else type(error).__name__


def train_run(
    path: str,
    config: dict[str, Any],
    threads: int,
    wandb: str | None = None,
    token: str | None = None,
    starts: Any = None,
) -> dict[str, Any]:
    """Train (or finish, or skip) one run; runs inside a worker process. The run's directory
    is locked while it trains; once it is, `token` is put on `starts` (a local worker's
    queue when None). Ctrl-C or SIGTERM stop it at its next episode end, with a checkpoint."""
    import torch

    from seqrank.config import TrainConfig
    from seqrank.training.launch import open_or_start
    from seqrank.training.stopping import stop_on_signals
    from seqrank.training.trainer import Trainer

    if _worker_stop is not None and _worker_stop.is_set():
        raise NotStarted("the sweep is stopping: run not started")
    torch.set_num_threads(threads)
    settings = TrainConfig(**config)
    started = open_or_start(Path(path), settings, settings.device, Trainer, wandb)
    stops: contextlib.AbstractContextManager[object] = contextlib.nullcontext()
    if started.finished:
        pass
    elif _worker_stop is not None:  # a local worker: its SIGTERM handler is installed
        started.trainer.stop_requested = _worker_stop
    else:  # Ray's cancel interrupts the main thread: asks the run to stop from here on,
        # before the start is announced (a cancel answering it must not be lost)
        stops = stop_on_signals(started.trainer.stop_requested.set, lambda text: None)
    try:
        with stops:
            queue = starts if starts is not None else _worker_starts
            if token is not None and queue is not None:
                queue.put(token)
            if started.finished:
                return {"status": "skipped", "summary": started.run.read_summary()}
            summary = started.trainer.train()
        return {"status": "resumed" if started.resumed else "trained", "summary": summary}
    finally:
        started.run.release()


RECANCEL_S = 30.0  # after a stop, Ray's cancel is sent again to a task still running


@dataclass(frozen=True)
class Ended:
    """A run's attempt that ended: with train_run's answer, a failure, or interrupted (stopped
    on request, or dropped before it began: which of the two, its start tells)."""

    handle: Any
    result: dict[str, Any] | None = None
    error: str | None = None
    interrupted: bool = False


def _interruption(error: BaseException) -> bool:
    """Whether a run's error is the sweep's stop rather than a failure."""
    from seqrank.training.loop import RunStopped

    return isinstance(error, RunStopped | KeyboardInterrupt | NotStarted)


class Backend(Protocol):
    def submit(self, run: PlannedRun, path: Path, token: str) -> Any: ...
    def started(self) -> list[str]: ...  # the tokens of runs that began since the last call
    def ended(self, timeout: float) -> list[Ended]: ...  # waits up to `timeout` seconds
    def cancel(self, handle: Any) -> bool: ...  # True: dropped before it began
    def stop(self) -> None: ...
    def close(self) -> None: ...


class LocalBackend:
    """A process pool (spawned processes: no GL or torch state shared), one thread per run."""

    def __init__(self, workers: int):
        context = multiprocessing.get_context("spawn")
        # a SimpleQueue's put is written before it returns: a run's start is readable before
        # its end is
        self.starts = context.SimpleQueue()
        self.pool = ProcessPoolExecutor(
            workers, mp_context=context, initializer=_start_worker, initargs=(self.starts,)
        )
        self.pending: set[Future[dict[str, Any]]] = set()

    def submit(self, run: PlannedRun, path: Path, token: str) -> Any:
        config = run.config.as_dict()
        future = self.pool.submit(train_run, str(path), config, 1, run.wandb, token)
        self.pending.add(future)
        return future

    def started(self) -> list[str]:
        tokens = []
        while not self.starts.empty():
            tokens.append(self.starts.get())
        return tokens

    def ended(self, timeout: float) -> list[Ended]:
        finished, self.pending = wait(self.pending, timeout, FIRST_COMPLETED)
        out = []
        for future in finished:
            error = future.exception()
            if error is None:
                out.append(Ended(future, result=future.result()))
            else:
                out.append(_ended_by(future, error))
        return out

    def cancel(self, handle: Any) -> bool:
        if handle.cancel():
            self.pending.discard(handle)
            return True
        return False

    def stop(self) -> None:
        """SIGTERM to every worker: each run stops at its next episode end with a checkpoint
        (a second call stops them at once); their ends then come back as interrupted."""
        # the executor keeps its worker processes only in a private field
        for process in list(getattr(self.pool, "_processes", {}).values()):
            with contextlib.suppress(ProcessLookupError):
                os.kill(process.pid, signal.SIGTERM)

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


def _ended_by(handle: Any, error: BaseException) -> Ended:
    if _interruption(error):
        return Ended(handle, interrupted=True)
    return Ended(handle, error=failure_text(error))


class RayBackend:
    """Ray tasks with per-run CPU and GPU fractions (several runs can share one GPU)."""

    def __init__(
        self, address: str | None, workers: int, cpus: float, gpus: float, temp: Path | None
    ):
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        import ray
        from ray.util.queue import Queue

        self.ray = ray
        options: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address is None:
            options["num_cpus"] = workers
            if temp is not None:
                options["_temp_dir"] = str(temp)
        ray.init(address=address, **options)
        self.task = ray.remote(num_cpus=cpus, num_gpus=gpus, max_retries=0)(train_run)
        # the runs' starts: an actor that takes no CPU from the runs
        self.starts = Queue(actor_options={"num_cpus": 0})
        self.pending: list[Any] = []
        self.stops, self.cancelled_at = 0, 0.0

    def submit(self, run: PlannedRun, path: Path, token: str) -> Any:
        config = run.config.as_dict()
        ref = self.task.remote(str(path.resolve()), config, 1, run.wandb, token, self.starts)
        self.pending.append(ref)
        return ref

    def started(self) -> list[str]:
        waiting = self.starts.qsize()
        return list(self.starts.get_nowait_batch(waiting)) if waiting else []

    def ended(self, timeout: float) -> list[Ended]:
        ready, self.pending = self.ray.wait(self.pending, num_returns=1, timeout=timeout)
        self._cancel_again()
        return [self._ended(ref) for ref in ready]

    def _cancel_again(self) -> None:
        """A cancel Ray did not deliver (seen: a task just begun trained on past its stop)
        is sent again after `RECANCEL_S`; a run stopping cleanly is done by then."""
        if self.stops and self.pending and time.monotonic() - self.cancelled_at > RECANCEL_S:
            self.cancelled_at = time.monotonic()
            for ref in self.pending:
                self.ray.cancel(ref)

    def _ended(self, ref: Any) -> Ended:
        errors = self.ray.exceptions
        try:
            return Ended(ref, result=self.ray.get(ref))
        except errors.TaskCancelledError:
            return Ended(ref, interrupted=True)
        except errors.WorkerCrashedError as error:  # what a forced cancel leaves
            return Ended(ref, interrupted=True) if self.stops else _ended_by(ref, error)
        except errors.RayError as error:
            if self.stops:  # a cancel may land anywhere in a task that is just beginning
                return Ended(ref, interrupted=True)  # its start (or none) tells which state
            return _ended_by(ref, getattr(error, "cause", None) or error)

    def cancel(self, handle: Any) -> bool:
        """Ask Ray to drop it; whether it had begun, its start (or none) tells."""
        self.ray.cancel(handle)
        return False

    def stop(self) -> None:
        """Cancel every task (a run interrupted at once; the second time, its worker ended):
        a run continues later from its last checkpoint."""
        self.stops += 1
        self.cancelled_at = time.monotonic()
        for ref in self.pending:
            self.ray.cancel(ref, force=self.stops > 1)

    def close(self) -> None:
        self.ray.shutdown()
