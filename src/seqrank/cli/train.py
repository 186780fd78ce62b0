"""`seqrank train`: every TrainConfig field is an option; --resume continues a run."""

from __future__ import annotations

import argparse
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from seqrank.choices import RewardSignal
from seqrank.cli.options import add_run_options, given_settings, problem_with_flags
from seqrank.config import TrainConfig, resolve_config
from seqrank.errors import UsageError
from seqrank.scale import resolve_scale
from seqrank.training.runs import RunDir

if TYPE_CHECKING:
    import torch

    from seqrank.training.launch import Started
    from seqrank.training.runtime import Runtime
    from seqrank.training.stopping import StopSignal


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
    """Ctrl-C or SIGTERM from here on stop the run at its next episode end, with a
    checkpoint; a second one stops at once, keeping the last checkpoint. Before training
    starts a second one stops at once too: a new run's directory is removed again, with a
    line saying so (nothing to resume yet); a resumed run's is left as it was."""
    from seqrank.training.runtime import resolve_device
    from seqrank.training.stopping import stop_on_signals
    from seqrank.training.trainer import Trainer

    stopping = threading.Event()
    with stop_on_signals(stopping.set, lambda text: _say(err, text)) as stop:
        try:
            started = prepare_run(args, err, Trainer, resolve_device)
        except (ValueError, FileNotFoundError, FileExistsError) as problem:
            raise UsageError(problem_with_flags(problem, args)) from None
        except KeyboardInterrupt:
            return stop.exit_code()
        if started is None:
            return 0  # --dry-run
        try:
            if started.finished:
                say_finished(started, err)
                return 0
            started.trainer.stop_requested = stopping
            return _train(started, out, err, args.quiet, stop)
        finally:
            started.run.release()


def _train(started: Started, out: Console, err: Console, quiet: bool, stop: StopSignal) -> int:
    from seqrank.training.loop import RunStopped

    trainer, run = started.trainer, started.run
    again = f"continue with: seqrank train --resume {run.path}"
    try:
        summary = _train_with_progress(trainer, started.config, err, quiet)
    except RunStopped as stopped:
        _say(err, f"stopped at step {stopped.step:,}, checkpoint saved; {again}")
        return stop.exit_code()
    except KeyboardInterrupt:
        kept = trainer.counters.last_checkpoint_step
        _say(err, f"stopped at once; the checkpoint of step {kept:,} is kept; {again}")
        return stop.exit_code()
    _print_summary(out, summary, run)
    return 0


def _say(err: Console, text: str) -> None:
    err.print(text, highlight=False, markup=False, soft_wrap=True)


def say_finished(started: Started, err: Console) -> None:
    path, steps = started.run.path, started.config.steps
    _say(err, f"run {path} is finished ({steps:,} steps, summary.json); nothing to resume")


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
    args: argparse.Namespace,
    err: Console,
    trainer_cls: Any,
    resolve_device: Any,
    check: Callable[[TrainConfig], None] | None = None,
) -> Started | None:
    """Start a new run or continue one (None after --dry-run); bad input raises ValueError.
    `check` refuses a new run's settings that the caller cannot serve, before anything is
    written (and in a dry run). The run directory stays locked by this process until
    `Started.run.release()`."""
    from seqrank.training.launch import continue_run, start_new

    if hasattr(args, "resume"):
        _refuse_new_settings(args)
        if args.dry_run:
            _dry_resume(args.resume, err)
            return None
        started = continue_run(args.resume, trainer_cls)
        if not started.finished:
            err.print(f"resuming {started.run.path} at step {started.trainer.counters.step}")
        return started
    new = new_run(args, resolve_device)
    # no --task: a replayed label file's task, else the default
    config = resolve_config(new.task if hasattr(args, "task") else None, new.scale, new.given)
    from seqrank.training.runtime import config_runtime

    config_runtime(config, new.device)  # before anything is written
    if check is not None:
        check(config)
    path = getattr(args, "out", None) or Path("seqrank-out/runs") / _run_name(config)
    RunDir.check_new(path)
    wandb = getattr(args, "wandb", None)
    if wandb is not None:
        _check_wandb(wandb)
    if args.dry_run:
        runtime = _check_with_env(config)
        _describe(config, path, new, err)
        _say(err, f"  training path: {_way(runtime)}")
        return None
    started = start_new(path, config, str(new.device), trainer_cls, wandb, lambda t: _say(err, t))
    way = _way(started.trainer.runtime)
    err.print(f"run directory: {path} ({new.scale} preset, device {new.device}, {way})")
    return started


def _way(runtime: Runtime) -> str:
    """How the run computes, as the user reads it (`--path auto` resolved; on a CPU, the
    torch threads it trains with)."""
    way = f"{runtime.path} path, {runtime.precision}"
    if runtime.device.type != "cpu":
        return way
    from seqrank.training.cpu_path import native_bf16, training_threads

    threads = training_threads(runtime.fast)
    way = f"{way}, {threads} torch thread{'s' if threads > 1 else ''}"
    if runtime.precision == "bf16" and not native_bf16():
        way += (
            "; this CPU has no native bf16, so bf16 is emulated and was measured 13x slower "
            "than fp32: --precision fp32 (or auto) trains faster"
        )
    return way


def _check_with_env(config: TrainConfig) -> Runtime:
    """The checks a run makes once its environment is built (episode length, memory, a
    replayed label file's features against the task's); where and how it would train."""
    from seqrank.envs import make_env
    from seqrank.training.feedback_parts import teacher_source
    from seqrank.training.trainer import check_fits

    env = make_env(config.task, config.seed)
    try:
        runtime = check_fits(config, env)
        if config.teacher_spec.kind == "replay":  # (`label online` brings its own source)
            teacher_source(config).check_compatible(config.task, env.obs_dim, env.act_dim)
    finally:
        env.close()
    return runtime


def _refuse_new_settings(args: argparse.Namespace) -> None:
    given = given_settings(args)
    if given or hasattr(args, "out") or hasattr(args, "scale") or hasattr(args, "wandb"):
        changed = ", ".join(f"--{k.replace('_', '-')}" for k in given) or "--out/--scale/--wandb"
        raise ValueError(f"--resume continues a run with its saved settings; drop {changed}")


def _dry_resume(path: Path, err: Console) -> None:
    run = RunDir.open(path)
    config = run.read_config()
    if run.finished:
        state = "finished: nothing to resume"
    else:
        checkpoint = run.load_checkpoint()
        step = 0 if checkpoint is None else checkpoint["counters"]["step"]
        state = f"resumes at step {step:,} of {config.steps:,}"
    _say(err, f"{path}: {config.task}, settings valid; {state} (dry run)")


def _describe(config: TrainConfig, path: Path, new: NewRun, err: Console) -> None:
    """What --dry-run prints: the resolved settings and where the run would go."""
    _say(
        err,
        f"settings valid ({new.scale} preset, device {new.device}); run directory would be "
        f"{path} (dry run: nothing written)",
    )
    for name, value in config.as_dict().items():
        _say(err, f"  {name} = {value}")


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
    from seqrank.envs.scoring import Metric, task_metric

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
    ]
    if reward.asks and final is not None:
        rows += _reference_rows(summary, run)
    success = summary["final_eval_success_rate"] or 0.0
    if task_metric(summary["task"], [success]) is Metric.SUCCESS:  # as `seqrank report` scores
        rows.append(("final success rate", f"{success:.0f}%"))
    rows += [
        ("feedback sessions", f"{summary['sessions']}"),
        ("questions asked", f"{summary['asked']}"),
        ("pairs inferred (wrong)", f"{summary['inferred']} ({summary['inferred_wrong']})"),
        ("wall time", f"{summary['wall_seconds'] / 60:.1f} min"),
        ("steps per second", f"{summary['steps_per_second']:.0f}"),
    ]
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
    rows = [("true-reward agent, same step (measured)", reference.describe())]
    if reference.mean > 0:
        share = summary["final_eval_return"] / reference.mean
        rows.append(("  this run's final return / its mean", f"{share:.2f}"))
    return [*rows, ("  measured in", reference.measured.split(":")[0])]
