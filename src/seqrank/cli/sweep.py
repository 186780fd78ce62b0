"""`seqrank sweep SPEC`: a grid of training runs from a TOML file, run locally or on Ray."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from seqrank.cli.options import int_between, number_between
from seqrank.errors import UsageError


def add_parser(commands: Any) -> None:
    sweep = commands.add_parser(
        "sweep",
        help="run a grid of training runs from a TOML sweep file (local processes or Ray)",
        description="Expand tasks x schemes x backbones x teachers x seeds x variants into "
        "`seqrank train` run directories under <out>/runs and run them. Finished runs are "
        "skipped, killed runs resume, failed runs are retried and then reported (exit 1). "
        "The sweep file format is in the documentation (Guides, Sweeps).",
    )
    sweep.add_argument("spec", type=Path, help="the sweep file (TOML)")
    sweep.add_argument(
        "--engine",
        choices=("local", "ray"),
        default="local",
        help="local: worker processes on this machine; ray: a Ray cluster (local)",
    )
    sweep.add_argument(
        "--workers",
        type=int_between(1, 1024),
        default=os.cpu_count() or 1,
        help="runs at once (default: the machine's cores; one thread each)",
    )
    sweep.add_argument("--ray-address", help="an existing Ray cluster (default: start one here)")
    sweep.add_argument(
        "--cpus-per-run", type=number_between(0.01, 1024), default=1.0, help="Ray: CPUs per run (1)"
    )
    sweep.add_argument(
        "--gpus-per-run",
        type=number_between(0, 64),
        default=0.0,
        help="Ray: GPU fraction per run (0; 0.25 = 4 per GPU)",
    )
    sweep.add_argument(
        "--dry-run", action="store_true", help="list the runs and their state, and stop"
    )
    sweep.add_argument(
        "--rerun-changed",
        action="store_true",
        help="rerun the runs whose saved settings differ from the sweep file's (their old "
        "directories move to <out>/replaced/); without it such runs stop the sweep",
    )
    sweep.set_defaults(handler=run)


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.dirs import DirLock, check_folder
    from seqrank.sweeps.folder import changed_runs, earlier_runs
    from seqrank.sweeps.spec import load_sweep

    ray_only = [
        flag
        for flag, given in (
            ("--ray-address", args.ray_address is not None),
            ("--cpus-per-run", args.cpus_per_run != 1.0),
            ("--gpus-per-run", args.gpus_per_run != 0.0),
        )
        if given
    ]
    if ray_only and args.engine != "ray":
        raise UsageError(f"{ray_only[0]} is a Ray setting: add --engine ray")
    try:
        sweep = load_sweep(args.spec)
        check_folder(sweep.out, "sweep folder")
        changed = dict(changed_runs(sweep))
        earlier = earlier_runs(sweep)
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    err.print(
        f"sweep {sweep.name}: {len(sweep.runs)} runs in {sweep.out / 'runs'}", highlight=False
    )
    if args.dry_run:
        _list_runs(sweep, changed, earlier, out)
        return 0
    if changed and not args.rerun_changed:
        raise UsageError(_changed_message(sweep, changed, args.spec))
    sweep.out.mkdir(parents=True, exist_ok=True)
    try:
        with DirLock(sweep.out, "sweep folder"):
            return _run(sweep, list(changed), earlier, args, out, err)
    except ValueError as problem:  # the folder in use, or a changed run being trained
        raise UsageError(str(problem)) from None


def _run(
    sweep: Any,
    changed: list[str],
    earlier: dict[str, str],
    args: argparse.Namespace,
    out: Console,
    err: Console,
) -> int:
    from seqrank.sweeps.folder import as_saved, set_aside, take_over
    from seqrank.sweeps.runner import RunStatus, StopRequests

    if earlier:
        take_over(sweep, earlier)
        err.print(f"{len(earlier)} baseline runs renamed to their names now", highlight=False)
    if changed:
        folder = set_aside(sweep, changed)
        err.print(f"{len(changed)} changed runs moved to {folder}; rerunning them", highlight=False)
    sweep = as_saved(sweep)
    stop = StopRequests()
    with _counting_signals(stop):
        status = _run_with_progress(sweep, _backend(args), err, stop)
    out.print(
        f"sweep {sweep.name}: {_counted(status.counts())}; state in {sweep.out / 'sweep.json'}"
    )
    if status.stopped:
        err.print(
            "interrupted: the running runs stopped (local: at an episode end with a "
            "checkpoint; Ray: from their last checkpoint), the queued ones never began; rerun "
            "the same command to continue",
            highlight=False,
        )
        return stop.exit_code()
    failed = [r for r in status.runs.values() if r.state is RunStatus.FAILED]
    for failure in failed:
        out.print(
            f"failed after {failure.attempts} attempts: {failure.name}: {failure.error}",
            highlight=False,
        )
    return 1 if failed else 0


def _counted(counts: dict[Any, int]) -> str:
    """`3 finished, 1 queued`: how many runs are in each state."""
    return ", ".join(f"{n} {state}" for state, n in sorted(counts.items()))


@contextlib.contextmanager
def _counting_signals(stop: Any) -> Iterator[None]:
    """SIGINT and SIGTERM count as stop requests, which the sweep forwards to its runs (so a
    signal sent to the sweep's process alone reaches them); the old handlers come back."""
    previous = {
        number: signal.signal(number, lambda signum, frame: stop.request(signum))
        for number in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def _list_runs(
    sweep: Any, changed: dict[str, list[str]], earlier: dict[str, str], out: Console
) -> None:
    """Each planned run and what a sweep would do with it."""
    for planned in sweep.runs:
        path = sweep.out / "runs" / planned.name
        if planned.name in earlier:
            path = sweep.out / "runs" / earlier[planned.name]
        if planned.name in changed:
            state = f"changed: {', '.join(changed[planned.name])}"
        elif (path / "summary.json").is_file():
            state = "finished"
        elif (path / "config.json").is_file():
            state = "started"
        else:
            state = "new"
        if planned.name in earlier:
            state += f", as {earlier[planned.name]}: renamed to this"
        out.print(f"{planned.name}  ({state})", highlight=False, soft_wrap=True)


def _changed_message(sweep: Any, changed: dict[str, list[str]], spec: Path) -> str:
    shown = [f"{name} ({', '.join(diff)})" for name, diff in list(changed.items())[:3]]
    more = f"; and {len(changed) - 3} more" if len(changed) > 3 else ""
    return (
        f"{len(changed)} runs in {sweep.out / 'runs'} were made with other settings than "
        f"{spec} gives now: {'; '.join(shown)}{more}; rerun them with --rerun-changed "
        f"(their directories move to {sweep.out / 'replaced'}), or restore the sweep file"
    )


def _backend(args: argparse.Namespace) -> Any:
    from seqrank.sweeps.engines import LocalBackend, RayBackend

    if args.engine != "ray":
        return LocalBackend(args.workers)
    try:
        return RayBackend(
            args.ray_address, args.workers, args.cpus_per_run, args.gpus_per_run, None
        )
    except ImportError:
        raise UsageError("--engine ray needs Ray: pip install 'seqrank[ray]'") from None


def _run_with_progress(sweep: Any, backend: Any, err: Console, stop: Any) -> Any:
    """Run the sweep with a bar of ended runs and a line per change of a run's state."""
    from seqrank.sweeps.runner import RunStatus, run_sweep

    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[counts]}"),
        TimeElapsedColumn(),
    )
    with Progress(*columns, console=err) as progress:
        bar = progress.add_task(sweep.name, total=len(sweep.runs), counts="")

        def event(status: Any, state: Any) -> None:
            counts = status.counts()
            done = counts.get(RunStatus.FINISHED, 0) + counts.get(RunStatus.FAILED, 0)
            progress.update(bar, completed=done, counts=_counted(counts))
            detail = f": {state.error}" if state.state is RunStatus.FAILED else ""
            if state.state is RunStatus.QUEUED and state.error:
                detail = f" (retry {state.attempts - 1}: {state.error})"
            err.print(f"{state.name}: {state.state}{detail}", highlight=False)

        return run_sweep(sweep, backend, event, stop)
