"""`seqrank offline train`: IQL on a fixed dataset, from its true reward or from a reward
learned on labels over its segments; --resume continues a stopped run."""

from __future__ import annotations

import argparse
import threading
import time
from collections.abc import Callable
from dataclasses import MISSING, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from seqrank.cli.options import Parser, problem_with_flags
from seqrank.errors import UsageError

if TYPE_CHECKING:
    from seqrank.offline.launch import OfflineStarted
    from seqrank.offline.settings import OfflineConfig
    from seqrank.training.stopping import StopSignal

MEANINGS = {
    "dataset": "a Minari dataset id in Minari's local folder ($MINARI_DATASETS_PATH, else "
    "~/.minari/datasets) or a dataset folder's path (`seqrank dataset make` writes one); "
    "required unless --resume (no default)",
    "task": "the task the dataset must be of (default: the task it records)",
    "reward": "true: the dataset's own reward (the ceiling); learned: labels over its "
    "segments, a reward model fit to them, the dataset relabelled",
    "scheme": "learned: pairwise, sequential, root or ranked",
    "teacher": "learned: who answers (the values train's --teacher takes)",
    "max_feedback": "learned: the questions asked in all",
    "segment_length": "learned: steps a segment",
    "session_questions": "learned: questions a session",
    "steps": "IQL updates",
    "eval_every": "updates between evaluations in the environment (each checkpoints)",
    "eval_episodes": "episodes an evaluation plays (the policy's mean action)",
    "seed": "seeds the networks, the batches, the questions and the evaluation episodes",
    "batch": "dataset rows an update",
    "hidden": "units a hidden layer (actor, twin critic, value)",
    "layers": "hidden layers",
    "actor_lr": "the actor's learning rate, decayed to 0 along a cosine",
    "critic_lr": "the twin critic's learning rate",
    "value_lr": "the value's learning rate",
    "discount": "gamma",
    "expectile": "IQL's tau: the expectile of Q that V tracks",
    "temperature": "IQL's beta: the advantage weight is exp(beta A), clipped at 100",
    "target_rate": "the target critic's soft update",
    "reward_scale": "auto (unit on Meta-World, as LiRE; returns elsewhere, as IQL on "
    "MuJoCo), returns (x 1000 / the spread of episode returns), unit (min-max onto [0, 1]) "
    "or none",
    "normalize_observations": "true: observations shifted and scaled by the dataset's mean "
    "and std (inside the policy: it acts on raw ones)",
    "device": "auto, cpu or cuda",
    "log_every": "updates between train rows",
}


def add_parser(commands: Any) -> None:
    offline = commands.add_parser(
        "offline",
        help="learn a policy from a fixed dataset (IQL)",
        description="Offline preference-based RL: a policy learned from a fixed dataset "
        "with Implicit Q-Learning, on its true reward or on a reward learned from labels "
        "over its segments.",
    )
    actions = offline.add_subparsers(dest="action", required=True, parser_class=Parser)
    train = actions.add_parser(
        "train",
        help="train IQL on a dataset and evaluate it in the environment",
        description="Train IQL (Kostrikov et al. 2022; the published MuJoCo "
        "hyperparameters by default) on a dataset's true reward (--reward true) or on a "
        "reward learned from --max-feedback questions of --scheme answered by --teacher "
        "(--reward learned); evaluate in the environment every --eval-every updates (return, "
        "and success rate on Meta-World), with a checkpoint each time.",
    )
    _add_options(train)
    train.set_defaults(handler=run)


def _add_options(parser: argparse.ArgumentParser) -> None:
    from seqrank.offline.settings import OfflineConfig

    parser.add_argument("--out", type=_folder, default=argparse.SUPPRESS,
                        help="run directory (default: seqrank-out/runs/offline_...)")  # fmt: skip
    parser.add_argument("--resume", type=_folder, metavar="RUN_DIR", default=argparse.SUPPRESS,
                        help="continue a stopped run from its last checkpoint")  # fmt: skip
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    for f in fields(OfflineConfig):
        kinds: dict[str, Callable[[str], Any]] = {
            "int": int,
            "float": float,
            "bool": _true_or_false,
        }
        kind = kinds.get(str(f.type), str)
        meaning = MEANINGS[f.name]
        if "default" not in meaning:
            default = "required" if f.default is MISSING else f.default
            meaning += f" (default: {str(default).lower() if kind is _true_or_false else default})"
        parser.add_argument(
            f"--{f.name.replace('_', '-')}",
            type=kind,
            default=argparse.SUPPRESS,
            metavar="true|false" if kind is _true_or_false else None,
            help=meaning,
        )
    parser.set_defaults(setting_flags=frozenset(f.name for f in fields(OfflineConfig)))


def _folder(text: str) -> Path:
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path names no run directory")
    return Path(text)


def _true_or_false(text: str) -> bool:
    if text not in ("true", "false"):
        raise argparse.ArgumentTypeError(f"{text!r} is neither true nor false")
    return text == "true"


def given(args: argparse.Namespace) -> dict[str, Any]:
    from seqrank.offline.settings import OfflineConfig

    return {f.name: getattr(args, f.name) for f in fields(OfflineConfig) if hasattr(args, f.name)}


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    """Ctrl-C or SIGTERM stop the run after a checkpoint of the current update."""
    from seqrank.training.stopping import stop_on_signals

    stopping = threading.Event()
    with stop_on_signals(stopping.set, lambda text: _say(err, text)) as stop:
        try:
            started = _start(args, err)
        except (ValueError, FileNotFoundError, FileExistsError) as problem:
            raise UsageError(problem_with_flags(problem, args)) from None
        except KeyboardInterrupt:
            return stop.exit_code()
        try:
            if started.finished:
                _say(err, f"run {started.run.path} is finished (summary.json); nothing to resume")
                return 0
            assert started.trainer is not None
            started.trainer.stop_requested = stopping
            return _train(started, out, err, args.quiet, stop)
        finally:
            started.run.release()


def _say(err: Console, text: str) -> None:
    err.print(text, highlight=False, markup=False, soft_wrap=True)


def _start(args: argparse.Namespace, err: Console) -> OfflineStarted:
    from seqrank.offline.launch import continue_run, start_new
    from seqrank.offline.settings import new_config

    if hasattr(args, "resume"):
        extra = [f"--{k.replace('_', '-')}" for k in given(args)] + ["--out"] * hasattr(args, "out")
        if extra:
            raise ValueError(
                f"--resume continues a run with its saved settings; drop {', '.join(extra)}"
            )
        started = continue_run(args.resume, say=lambda text: _say(err, text))
        if not started.finished:
            assert started.trainer is not None
            _say(err, f"resuming {started.run.path} at update {started.trainer.counters.step:,}")
        return started
    settings = given(args)
    if "dataset" not in settings:
        raise ValueError("--dataset is needed (or --resume RUN_DIR)")
    config = new_config(settings)
    path = getattr(args, "out", None) or Path("seqrank-out/runs") / _run_name(config)
    started = start_new(path, config, say=lambda text: _say(err, text))
    _say(err, f"run directory: {path}")
    return started


def _run_name(config: OfflineConfig) -> str:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    name = Path(config.dataset.rstrip("/")).name.replace(":", "-")
    how = "true-reward" if config.reward == "true" else f"{config.scheme}_{config.teacher}"
    return f"offline_{name}_{how}_seed{config.seed}_{stamp}".replace("/", "-")


def _train(
    started: OfflineStarted, out: Console, err: Console, quiet: bool, stop: StopSignal
) -> int:
    from seqrank.training.loop import RunStopped

    trainer, run = started.trainer, started.run
    assert trainer is not None
    again = f"continue with: seqrank offline train --resume {run.path}"
    try:
        summary = trainer.train() if quiet else _with_progress(started, err)
    except RunStopped as stopped:
        _say(err, f"stopped at update {stopped.step:,}, checkpoint saved; {again}")
        return stop.exit_code()
    except KeyboardInterrupt:
        _say(err, f"stopped at once; the last checkpoint is kept; {again}")
        return stop.exit_code()
    _print_summary(out, summary, run.path)
    return 0


def _with_progress(started: OfflineStarted, err: Console) -> dict[str, Any]:
    trainer, config = started.trainer, started.config
    assert trainer is not None
    columns = (TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.fields[live]}"), TimeRemainingColumn())  # fmt: skip
    with Progress(*columns, console=err) as progress:
        bar = progress.add_task(
            trainer.dataset.task, total=config.steps, completed=trainer.counters.step, live=""
        )

        def report(step: int, live: dict[str, Any]) -> None:
            ret = live["eval_return"]
            text = f"return {'-' if ret is None else f'{ret:.1f}'} | {live['ups']:.0f} updates/s"
            progress.update(bar, completed=step, live=text)
            evaluated = step % config.eval_every == 0 or step == config.steps
            if not err.is_terminal and evaluated:
                err.print(f"update {step:,}/{config.steps:,} | {text}", highlight=False)

        trainer.progress = report
        return trainer.train()


def _print_summary(out: Console, summary: dict[str, Any], path: Path) -> None:
    from seqrank.envs.scoring import Metric, task_metric

    how = "its true reward" if summary["reward"] == "true" else (
        f"a reward learned from {summary['max_feedback']} {summary['scheme']} questions "
        f"({summary['teacher']})"
    )  # fmt: skip
    out.print(f"[bold]{summary['task']}[/bold]: IQL on {how}, {summary['steps']:,} updates")
    final, best = summary["final_eval_return"], summary["best_eval_return"]
    out.print(f"  final eval return {final:.1f} (best {best:.1f}); the dataset's episodes "
              f"average {summary['dataset_return_mean']:.1f}")  # fmt: skip
    success = summary["final_eval_success_rate"] or 0.0
    if task_metric(summary["task"], [success]) is Metric.SUCCESS:
        out.print(f"  final success rate {success:.0f}%")
    out.print(f"  {summary['wall_seconds'] / 60:.1f} min, {summary['updates_per_second']:.0f} "
              f"updates/s; run directory: {path}")  # fmt: skip
