"""`seqrank train`: every TrainConfig field is an option; --resume continues a run."""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from seqrank.choices import RewardSignal
from seqrank.cli.options import add_run_options, given_settings
from seqrank.config import TrainConfig, resolve_config
from seqrank.errors import UsageError
from seqrank.scale import resolve_scale
from seqrank.training.runs import RunDir

if TYPE_CHECKING:
    import torch


def add_parser(commands: Any) -> None:
    train = commands.add_parser(
        "train",
        help="train an agent from preferences (PEBBLE or MRN), or a baseline",
        description="Train SAC from a reward learned on preferences. Defaults: walker_walk, "
        "sequential scheme, oracle teacher, PEBBLE, the paper's Table 2 settings on a GPU "
        "and the small preset on a CPU (--scale auto). Every setting below overrides. "
        "Baselines: --reward true trains the same agent on the environment's reward (no "
        "feedback, no pre-training); --reward none pre-trains, then learns from the "
        "untrained reward model (the floor that shows what feedback adds).",
    )
    add_run_options(train)
    train.add_argument("--quiet", action="store_true", help="no progress bar")
    train.set_defaults(handler=run)


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.training.runtime import resolve_device
    from seqrank.training.trainer import Trainer

    try:
        trainer, config, run_dir = prepare_run(args, err, Trainer, resolve_device)
    except (ValueError, FileNotFoundError, FileExistsError) as problem:
        raise UsageError(str(problem)) from None
    summary = _train_with_progress(trainer, config, err, args.quiet)
    _print_summary(out, summary, run_dir)
    return 0


@dataclass(frozen=True)
class NewRun:
    """A new run's settings: options given (less the task), device, preset scale and task."""

    given: dict[str, Any]
    device: torch.device
    scale: str
    task: str


def new_run(args: argparse.Namespace, resolve_device: Any) -> NewRun:
    given = given_settings(args)
    device = resolve_device(given.get("device", "auto"))
    scale = resolve_scale(getattr(args, "scale", "auto"), device)
    return NewRun(given, device, scale, given.pop("task", TrainConfig.task))


def prepare_run(
    args: argparse.Namespace, err: Console, trainer_cls: Any, resolve_device: Any
) -> Any:
    """Build the trainer of a new or resumed run; bad input raises ValueError."""
    if hasattr(args, "resume"):
        return _resume_run(args, err, trainer_cls)
    new = new_run(args, resolve_device)
    config = resolve_config(new.task, new.scale, new.given)
    from seqrank.training.runtime import config_runtime

    config_runtime(config, new.device)  # before anything is written
    path = getattr(args, "out", None) or Path("seqrank-out/runs") / _run_name(config)
    wandb = getattr(args, "wandb", None)
    if wandb is not None:
        _check_wandb(wandb)
    run = RunDir.create(path, config, str(new.device), wandb)
    trainer = trainer_cls(config, run)
    err.print(f"run directory: {run.path} ({new.scale} preset, device {new.device})")
    return trainer, config, run


def _resume_run(args: argparse.Namespace, err: Console, trainer_cls: Any) -> Any:
    given = given_settings(args)
    if given or hasattr(args, "out") or hasattr(args, "scale") or hasattr(args, "wandb"):
        changed = ", ".join(f"--{k.replace('_', '-')}" for k in given) or "--out/--scale/--wandb"
        raise ValueError(f"--resume continues a run with its saved settings; drop {changed}")
    run = RunDir.open(args.resume)
    config = run.read_config()
    from seqrank.training.trainer import open_trainer

    trainer, state = open_trainer(trainer_cls, config, run)
    if state is None:  # killed before its first checkpoint: start over, dropping what it logged
        run.truncate_metrics(0)
    err.print(f"resuming {run.path} at step {trainer.counters.step}")
    return trainer, config, run


def _check_wandb(project: str) -> None:
    if not project.strip():
        raise ValueError("--wandb needs a project name")
    try:
        import wandb  # noqa: F401
    except ImportError:
        raise ValueError("--wandb needs Weights & Biases: pip install 'seqrank[wandb]'") from None


def _run_name(config: TrainConfig) -> str:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    task = config.task.replace(":", "-")
    if not config.reward.asks:
        return f"{task}_{config.reward.method}_seed{config.seed}_{stamp}"
    teacher = config.teacher_spec.short_name
    return f"{task}_{config.scheme}_{teacher}_{config.backbone}_seed{config.seed}_{stamp}"


def _train_with_progress(trainer: Any, config: TrainConfig, err: Console, quiet: bool) -> Any:
    if quiet:
        return trainer.train()
    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[live]}"),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=err) as progress:
        task = progress.add_task(
            config.task, total=config.steps, completed=trainer.counters.step, live=""
        )

        def report(step: int, live: dict[str, Any]) -> None:
            ret = live["eval_return"]
            text = (
                f"return {'-' if ret is None else f'{ret:.1f}'} | asked {live['asked']} "
                f"inferred {live['inferred']} | {live['sps']:.0f} steps/s"
            )
            progress.update(task, completed=step, live=text)
            if not err.is_terminal and step % config.eval_every == 0:
                # piped output (logs, CI) gets no live bar: print a line per evaluation
                err.print(f"step {step:,}/{config.steps:,} | {text}", highlight=False)

        trainer.progress = report
        return trainer.train()


def _print_summary(out: Console, summary: dict[str, Any], run: RunDir) -> None:
    reward = RewardSignal(summary.get("reward", "learned"))
    method = (
        f"{summary['scheme']} scheme, {summary['teacher']} teacher, {summary['backbone']}"
        if reward.asks
        else f"the {reward.method} baseline (no feedback)"
    )
    out.print(f"[bold]{summary['task']}[/bold]: {method}")
    table = Table(show_header=False)
    table.add_column("what")
    table.add_column("value", justify="right")
    final, best = summary["final_eval_return"], summary["best_eval_return"]
    rows = [
        ("steps", f"{summary['steps']}"),
        ("final eval return", "-" if final is None else f"{final:.1f}"),
        ("best eval return", "-" if best is None else f"{best:.1f}"),
        ("final success rate", f"{summary['final_eval_success_rate']:.0f}%"),
        ("feedback sessions", f"{summary['sessions']}"),
        ("questions asked", f"{summary['asked']}"),
        ("pairs inferred (wrong)", f"{summary['inferred']} ({summary['inferred_wrong']})"),
        ("wall time", f"{summary['wall_seconds'] / 60:.1f} min"),
        ("steps per second", f"{summary['steps_per_second']:.0f}"),
    ]
    rows[3:3] = _reference_rows(summary, run) if reward.asks and final is not None else []
    for name, value in rows:
        table.add_row(name, value)
    out.print(table)
    curve = summary["eval_curve"]
    if curve:
        out.print("evaluation return by step:")
        top = max(max(r for _, r in curve), 1e-9)
        for step, value in curve:
            out.print(f"  {step:>9,}  {value:8.1f}  {'#' * int(40 * max(value, 0) / top)}")
        from seqrank.plots import plot_curve

        name = summary["scheme"] if reward.asks else reward.method
        plot_curve(curve, run.path / "returns.png", f"{summary['task']} ({name})")
    out.print(f"run directory: {run.path}")


def _reference_rows(summary: dict[str, Any], run: RunDir) -> list[tuple[str, str]]:
    """The shipped true-reward measurement at this run's final step, beside its return."""
    from seqrank.reference import reference_for

    reference = reference_for(run.read_config().as_dict(), summary["steps"])
    if reference is None:
        return [("true-reward agent", "not measured for these settings (--reward true)")]
    return [
        ("true-reward agent, same step (measured)", reference.describe()),
        ("  measured in", reference.measured.split(":")[0]),
    ]
