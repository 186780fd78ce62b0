"""A sweep's runs through an engine (`engines.Backend`), with retries, and what it says of them.

Every run is, at each moment, in one of `RunStatus`; `<out>/sweep.json` is rewritten
(atomically) on every change, and stays true when the sweep is stopped: a run that finished
says finished, one interrupted mid-way says stopped, one that never began says queued. A
failed run is tried again `retries` times and then reported, never dropped.
"""

from __future__ import annotations

import json
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from seqrank.sweeps.engines import Backend, Ended
from seqrank.sweeps.spec import PlannedRun, Sweep

# how often the sweep looks for started runs and stop requests while it waits for ends
POLL_SECONDS = 0.5


class RunStatus(StrEnum):
    QUEUED = "queued"  # waiting for a worker (or never begun: the sweep stopped first)
    RUNNING = "running"  # its worker holds the run's directory
    FINISHED = "finished"  # it has its summary (`outcome` says how)
    STOPPED = "stopped"  # interrupted on request; the same sweep continues it
    FAILED = "failed"  # its last attempt failed (`error`)


@dataclass
class RunState:
    name: str
    state: RunStatus = RunStatus.QUEUED
    attempts: int = 0
    error: str | None = None
    final_eval_return: float | None = None
    # a finished run: trained (from the start), resumed (from a checkpoint), or skipped
    # (finished before this sweep began)
    outcome: str | None = None


@dataclass
class SweepStatus:
    runs: dict[str, RunState] = field(default_factory=dict)
    stopped: bool = False  # the sweep was asked to stop

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for run in self.runs.values():
            out[run.state] = out.get(run.state, 0) + 1
        return out


class StopRequests:
    """The stop signals the sweep has had, counted by a signal handler; the sweep forwards
    each to its runs (the first: stop at the next episode end; a second: at once)."""

    def __init__(self) -> None:
        self.count = 0
        self.signum: int | None = None

    def request(self, signum: int = signal.SIGINT) -> None:
        if self.signum is None:
            self.signum = signum
        self.count += 1

    def exit_code(self) -> int:
        return 128 + (self.signum or signal.SIGINT)


Event = Callable[[SweepStatus, RunState], None]


def run_sweep(
    sweep: Sweep,
    backend: Backend,
    on_event: Event | None = None,
    stop: StopRequests | None = None,
) -> SweepStatus:
    """Run every planned run to completion or failure, or until `stop` has a request (then
    no run starts and the running ones stop); returns the final status."""
    tracker = _Tracker(sweep, backend, on_event)
    stop = stop if stop is not None else StopRequests()
    forwarded = 0
    try:
        for run in sweep.runs:
            tracker.submit(run)
        tracker.save()
        while tracker.in_flight:
            if stop.count > forwarded:
                if not forwarded:
                    tracker.drop_queued()
                forwarded = stop.count
                backend.stop()
            tracker.note_starts()
            for ended in backend.ended(POLL_SECONDS):
                tracker.note_starts()  # a start is readable before its end
                tracker.end(ended, retry=not stop.count)
    finally:
        backend.close()
    tracker.status.stopped = bool(stop.count)
    return tracker.status


class _Tracker:
    """The runs in flight and every run's state; each change is saved and reported."""

    def __init__(self, sweep: Sweep, backend: Backend, on_event: Event | None):
        self.sweep, self.backend, self.on_event = sweep, backend, on_event
        self.status = SweepStatus({r.name: RunState(r.name) for r in sweep.runs})
        self.in_flight: dict[Any, PlannedRun] = {}

    def submit(self, run: PlannedRun) -> None:
        state = self.status.runs[run.name]
        state.state, state.attempts = RunStatus.QUEUED, state.attempts + 1
        token = f"{state.attempts}:{run.name}"
        handle = self.backend.submit(run, self.sweep.out / "runs" / run.name, token)
        self.in_flight[handle] = run

    def note_starts(self) -> None:
        for token in self.backend.started():
            attempt, name = token.split(":", 1)
            state = self.status.runs[name]
            # a late start of an earlier attempt says nothing of this one
            if state.state is RunStatus.QUEUED and state.attempts == int(attempt):
                self.change(state, RunStatus.RUNNING)

    def drop_queued(self) -> None:
        """Cancel the runs that have not begun; they stay queued."""
        for handle, run in list(self.in_flight.items()):
            queued = self.status.runs[run.name].state is RunStatus.QUEUED
            if queued and self.backend.cancel(handle):
                del self.in_flight[handle]
        self.save()

    def end(self, ended: Ended, retry: bool) -> None:
        run = self.in_flight.pop(ended.handle)
        state = self.status.runs[run.name]
        if ended.result is not None:
            state.error, state.outcome = None, ended.result["status"]
            state.final_eval_return = ended.result["summary"].get("final_eval_return")
            self.change(state, RunStatus.FINISHED)
        elif ended.interrupted:
            began = state.state is RunStatus.RUNNING
            self.change(state, RunStatus.STOPPED if began else RunStatus.QUEUED)
        elif retry and state.attempts <= self.sweep.retries:
            state.error = ended.error
            self.submit(run)
            self.change(state, RunStatus.QUEUED)
        else:
            state.error = ended.error
            self.change(state, RunStatus.FAILED)

    def change(self, state: RunState, to: RunStatus) -> None:
        state.state = to
        self.save()
        if self.on_event is not None:
            self.on_event(self.status, state)

    def save(self) -> None:
        out = self.sweep.out
        out.mkdir(parents=True, exist_ok=True)
        payload = {
            "name": self.sweep.name,
            "updated": time.strftime("%Y-%m-%dT%H:%M:%S"),
            "counts": self.status.counts(),
            "runs": [vars(r) for r in self.status.runs.values()],
        }
        partial = out / "sweep.json.part"
        partial.write_text(json.dumps(payload, indent=2))
        partial.replace(out / "sweep.json")
