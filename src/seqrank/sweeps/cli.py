"""`seqrank sweep SPEC` and `seqrank report RUNS_DIR`."""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from seqrank.errors import UsageError


def add_sweep_parsers(commands: Any) -> None:
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

    report = commands.add_parser(
        "report",
        help="tables (mean ± std, IQM with CIs, probability of improvement) and plots of runs",
        description="Read every run directory under RUNS_DIR (finished or not) and write "
        "report.md, report.csv, report.json and PNG plots.",
    )
    report.add_argument("runs_dir", type=Path)
    report.add_argument("--out", type=Path, help="(default: RUNS_DIR/report)")
    report.add_argument("--bootstrap", type=int, default=2000, help="resamples (2000)")
    report.add_argument("--seed", type=int, default=0, help="bootstrap seed (0)")
    report.add_argument("--no-plots", action="store_true")


def run_sweep_command(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.sweeps.engines import LocalBackend, RayBackend, run_sweep
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
        for run in sweep.runs:
            out.print(run.name, highlight=False)
        return 0
    if args.engine == "ray":
        try:
            backend: Any = RayBackend(
                args.ray_address, args.workers, args.cpus_per_run, args.gpus_per_run, None
            )
        except ImportError:
            raise UsageError("--engine ray needs Ray: pip install 'seqrank[ray]'") from None
    else:
        backend = LocalBackend(args.workers)
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

        status = run_sweep(sweep, backend, event)
    failed = [r for r in status.runs.values() if r.state == "failed"]
    out.print(f"sweep {sweep.name}: {status.counts()}; state in {sweep.out / 'sweep.json'}")
    for failure in failed:
        out.print(
            f"failed after {failure.attempts} attempts: {failure.name}: {failure.error}",
            highlight=False,
        )
    return 1 if failed else 0


def run_report_command(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.report.report import build_report, format_markdown, write_report

    if args.bootstrap < 100:
        raise UsageError(f"--bootstrap {args.bootstrap}: use at least 100 resamples")
    try:
        report = build_report(args.runs_dir, args.bootstrap, args.seed)
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    written = write_report(report, args.out or args.runs_dir / "report", not args.no_plots)
    out.print(format_markdown(report), markup=False, highlight=False)
    err.print("wrote " + ", ".join(str(p) for p in written), highlight=False)
    return 0
