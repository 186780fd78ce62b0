"""`seqrank sweep SPEC`: a grid of training runs from a TOML file, run locally or on Ray."""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from seqrank.errors import UsageError


def add_parser(commands: Any) -> None:
    sweep = commands.add_parser(
        "sweep",
        help="run a grid of training runs from a TOML sweep file (local processes or Ray)",
        description="Expand tasks x schemes x backbones x teachers x seeds x variants into "
        "`seqrank train` run directories under <out>/runs and run them. Finished runs are "
        "skipped, killed runs resume, failed runs are retried and then reported (exit 1). "
        "The sweep file format is in the README.",
    )
    sweep.add_argument("spec", type=Path, help="the sweep file (TOML)")
    sweep.add_argument("--engine", choices=("local", "ray"), default="local")
    sweep.add_argument(
        "--workers",
        type=int,
        default=os.cpu_count() or 1,
        help="runs at once (default: the machine's cores; one thread each)",
    )
    sweep.add_argument("--ray-address", help="an existing Ray cluster (default: start one here)")
    sweep.add_argument("--cpus-per-run", type=float, default=1.0, help="Ray: CPUs per run (1)")
    sweep.add_argument(
        "--gpus-per-run",
        type=float,
        default=0.0,
        help="Ray: GPU fraction per run (0; 0.25 = 4 per GPU)",
    )
    sweep.add_argument("--dry-run", action="store_true", help="list the runs and stop")
    sweep.set_defaults(handler=run)


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.sweeps.spec import load_sweep

    if args.workers < 1:
        raise UsageError(f"--workers {args.workers}: must be at least 1")
    if args.cpus_per_run <= 0 or args.gpus_per_run < 0:
        raise UsageError("--cpus-per-run must be > 0 and --gpus-per-run >= 0")
    try:
        sweep = load_sweep(args.spec)
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    err.print(
        f"sweep {sweep.name}: {len(sweep.runs)} runs in {sweep.out / 'runs'}", highlight=False
    )
    if args.dry_run:
        for planned in sweep.runs:
            out.print(planned.name, highlight=False)
        return 0
    status = _run_with_progress(sweep, _backend(args), err)
    failed = [r for r in status.runs.values() if r.state == "failed"]
    out.print(f"sweep {sweep.name}: {status.counts()}; state in {sweep.out / 'sweep.json'}")
    for failure in failed:
        out.print(
            f"failed after {failure.attempts} attempts: {failure.name}: {failure.error}",
            highlight=False,
        )
    return 1 if failed else 0


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


def _run_with_progress(sweep: Any, backend: Any, err: Console) -> Any:
    """Run the sweep with a bar of ended runs and a line per change of a run's state."""
    from seqrank.sweeps.engines import run_sweep

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
            ended = sum(n for s, n in counts.items() if s not in ("running", "pending"))
            text = ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
            progress.update(bar, completed=ended, counts=text)
            detail = f": {state.error}" if state.state == "failed" else ""
            if state.state == "running":
                detail = f" (retry {state.attempts - 1}: {state.error})"
            err.print(f"{state.name}: {state.state}{detail}", highlight=False)

        return run_sweep(sweep, backend, event)
