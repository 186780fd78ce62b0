"""`seqrank reward-bench`: what each scheme's answers teach the reward model, measured on
saved trajectory pools without RL (pool, run, score)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from seqrank.cli.options import Parser, int_between, names, seed_number
from seqrank.cli.reward_bench_options import add_crowd_evidence, add_grid_axes, add_grid_sizes
from seqrank.cli.reward_bench_report import add_report, write_report
from seqrank.errors import UsageError
from seqrank.feedback.schemes import SchemeName

if TYPE_CHECKING:
    from seqrank.feedback.replay import ReplaySource
    from seqrank.training.launch import Started

SCHEMES = [s.value for s in SchemeName]
POOL_STEPS = 50_000  # `reward-bench pool`'s true-reward training steps, by default


def teacher_list(text: str) -> list[str]:
    """`--teachers`: the shared list syntax of `split_teachers` (`seqrank simulate`'s too)."""
    from seqrank.feedback.teachers import split_teachers

    try:
        return split_teachers(text)
    except ValueError as problem:
        raise argparse.ArgumentTypeError(str(problem)) from None


def add_parser(commands: Any) -> None:
    bench = commands.add_parser(
        "reward-bench",
        help="reward learning per question, by scheme, on saved trajectory pools (no RL)",
        description="The schemes' reward learning measured without RL's noise: build a pool "
        "of real episodes (pool), run the grid of schemes x teachers x learners x seeds (run), "
        "or score labels exported from the labelling page (score). Measures on held-out segments: "
        "preference accuracy, Spearman rank correlation, accuracy in the top quarter, recall of "
        "the top 10%, regret of picking the best of 10, wrong inferred labels.",
    )
    actions = bench.add_subparsers(dest="action", required=True, parser_class=Parser)
    _add_pool(actions)
    _add_grid(actions)
    _add_score(actions)
    add_report(actions)


def _add_pool(actions: Any) -> None:
    pool = actions.add_parser("pool", help="build a pool: a true-reward run's episodes + random")
    pool.add_argument(
        "--task",
        default=None,
        help="the task of the true-reward run that is trained for the pool (walker_walk); "
        "with --from-dataset, the task of a dataset that names none (a foreign one); "
        "ignored with --from-run, whose task it is",
    )
    pool.add_argument(
        "--from-run",
        type=Path,
        help="take the episodes this run directory kept (its episodes_kept) instead of "
        "training one",
    )
    pool.add_argument(
        "--from-dataset",
        help="take the episodes of this offline dataset (a Minari dataset id or folder, "
        "`seqrank dataset make`) instead of training a run",
    )
    pool.add_argument(
        "--until-step",
        type=int_between(1, 10**8),
        help="with --from-run: only the episodes that ended by this step (the pool of a "
        "shorter run of the same settings; default: every kept episode)",
    )
    pool.add_argument(
        "--steps",
        type=int_between(1, 10**8),
        help="true-reward training steps, on the CPU, in <out>.run/ (50000; not with "
        "--from-dataset)",
    )
    pool.add_argument("--seed", type=seed_number, default=0, help="(0)")
    pool.add_argument(
        "--random-episodes",
        type=int_between(0, 10_000),
        help="episodes of random actions added to the pool (5; 0 with --from-dataset)",
    )
    pool.add_argument(
        "--out", type=Path, required=True, help="the new pool file (.npz); not one already there"
    )
    pool.set_defaults(handler=run_pool)


def _add_grid(actions: Any) -> None:
    grid = actions.add_parser("run", help="run the grid and print the table")
    grid.add_argument(
        "--pool", type=Path, action="append", required=True, help="a pool file; repeatable"
    )
    grid.add_argument(
        "--schemes",
        type=names(SCHEMES, "scheme"),
        default=SCHEMES,
        help=f"comma-separated ({','.join(SCHEMES)})",
    )
    grid.add_argument(
        "--teachers",
        type=teacher_list,
        default=["oracle"],
        help="scripted teachers: presets (oracle, mistake, noisy, skip, myopic, equal), "
        "each optionally followed by its knobs, comma-separated: a knob=value part belongs "
        "to the teacher before it, e.g. oracle,mistake,eps_mistake=0.2; ';' also separates "
        "teachers, e.g. 'oracle;beta=1'; or a simulated crowd, crowd:oracle+mistake+noisy "
        "(oracle)",
    )
    add_grid_axes(grid)
    add_crowd_evidence(grid)
    grid.add_argument("--seeds", type=int_between(1, 10_000), default=3, help="seeds 0..N-1 (3)")
    add_grid_sizes(grid)
    grid.set_defaults(handler=run_grid)


def _add_score(actions: Any) -> None:
    score = actions.add_parser("score", help="score exported labels (JSONL) on a pool")
    score.add_argument("labels", type=Path, help="a label file from `seqrank labels export`")
    score.add_argument("--pool", type=Path, required=True, help="a pool of the same task")
    score.add_argument(
        "--seed", type=seed_number, default=0, help="seeds the reward model's training (0)"
    )
    score.set_defaults(handler=run_score)


def run_pool(args: argparse.Namespace, out: Console, err: Console) -> int:
    """Only the checks of the input run under `UsageError`: a fault in training or in
    building the pool is the code's, and surfaces as a traceback."""
    from seqrank.rewardbench.pool import kept_episodes, pool_from_kept, save_pool

    if args.from_dataset is not None:
        return _pool_from_dataset(args, out)
    args.random_episodes = 5 if args.random_episodes is None else args.random_episodes
    args.steps = POOL_STEPS if args.steps is None else args.steps
    try:
        path = _new_pool_file(args.out)
        if args.until_step is not None and args.from_run is None:
            raise ValueError("--until-step takes part of a run given with --from-run")
        started = None if args.from_run is not None else _start_pool_run(args)
    except (ValueError, FileNotFoundError) as problem:
        raise UsageError(str(problem)) from None
    run_path = args.from_run if started is None else _train_for_pool(started, args, err)
    try:
        kept = kept_episodes(run_path, args.until_step)
        kept.check_size(args.random_episodes)
    except (ValueError, FileNotFoundError) as problem:
        raise UsageError(str(problem)) from None
    pool = pool_from_kept(kept, args.random_episodes, args.seed)
    save_pool(pool, path)
    _say_pool(pool, path, out)
    return 0


def _new_pool_file(out: Path) -> Path:
    """The file a pool is written to (numpy adds .npz to a name without it); one that is
    there already is refused (a ValueError) rather than overwritten."""
    from seqrank.dirs import check_file

    path = out if str(out).endswith(".npz") else out.with_name(out.name + ".npz")
    for given in dict.fromkeys((out, path)):
        check_file(given, "pool file")
    if path.exists():
        raise ValueError(f"pool file {path} already exists; choose another --out or remove it")
    return path


def _pool_from_dataset(args: argparse.Namespace, out: Console) -> int:
    from seqrank.offline.minari_io import load_dataset
    from seqrank.rewardbench.pool import check_pool_size, pool_from_dataset, save_pool

    random_count = args.random_episodes or 0
    try:
        if args.from_run is not None or args.until_step is not None:
            raise ValueError("--from-dataset takes a dataset's episodes: leave out --from-run "
                             "and --until-step")  # fmt: skip
        if args.steps is not None:
            raise ValueError(
                f"--steps {args.steps} trains a run for the pool; --from-dataset takes a "
                "dataset's episodes and trains none: leave out --steps"
            )
        path = _new_pool_file(args.out)
        dataset = load_dataset(args.from_dataset, task=args.task)
        check_pool_size(dataset.episode_count + random_count, f"dataset {args.from_dataset}")
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    pool = pool_from_dataset(dataset, random_count, args.seed)
    save_pool(pool, path)
    _say_pool(pool, path, out)
    return 0


def _say_pool(pool: Any, path: Path, out: Console) -> None:
    returns = pool.returns
    out.print(
        f"pool {path}: {len(pool)} episodes of {pool.task} (returns {returns.min():.0f} to "
        f"{returns.max():.0f}, median {float(sorted(returns)[len(returns) // 2]):.0f})",
        highlight=False,
    )


def _start_pool_run(args: argparse.Namespace) -> Started:
    """The true-reward run that keeps every episode (in `<out>.run/`), made or continued:
    a bad --task or a folder of another run is a ValueError."""
    from seqrank.config import resolve_config
    from seqrank.training.launch import open_or_start
    from seqrank.training.trainer import Trainer

    settings = {"reward": "true", "steps": args.steps, "seed": args.seed, "device": "cpu"}
    task = args.task if args.task is not None else "walker_walk"
    config = resolve_config(task, "small", {**settings, "episodes_kept": args.steps})
    return open_or_start(args.out.with_suffix(".run"), config, "cpu", Trainer)


def _train_for_pool(started: Started, args: argparse.Namespace, err: Console) -> Path:
    """The pool run trained to its end; its folder."""
    folder = args.out.with_suffix(".run")
    try:
        if started.finished:
            return folder
        trainer = started.trainer
        err.print(f"training on the true reward for {args.steps:,} steps in {folder}")
        with Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            console=err,
        ) as progress:
            bar = progress.add_task("pool run", total=args.steps, completed=trainer.counters.step)
            trainer.progress = lambda step, live: progress.update(bar, completed=step)
            trainer.train()
    finally:
        started.run.release()
    return folder


def _check_scripted(teachers: list[str]) -> None:
    from seqrank.feedback.teachers import CROWD_PREFIX, parse_crowd, parse_scripted_teacher

    for teacher in teachers:
        if teacher == "human" or teacher.startswith("replay:"):
            raise ValueError(
                f"teacher {teacher!r}: the grid asks scripted teachers only (labels from "
                "the page are scored with `seqrank reward-bench score`)"
            )
        if teacher.startswith(CROWD_PREFIX):
            parse_crowd(teacher)  # a simulated crowd of scripted members
        else:
            parse_scripted_teacher(teacher)


def _check_segment_length(pool: Any, path: Any, length: int) -> None:
    """A segment no episode of the pool is long enough to hold is refused (a shorter
    episode gives its whole self, padded, as in training)."""
    longest = int(pool.length.max())
    if length > longest:
        raise ValueError(
            f"--segment-length {length} is longer than every episode of pool {path} (the "
            f"longest has {longest} steps); accepted: 1 to {longest}"
        )


def run_grid(args: argparse.Namespace, out: Console, err: Console) -> int:
    """The input (pools, folder, teachers, settings; under --window-steps, each pool's
    windows) is checked before anything is written or run; a cell that fails afterwards
    is a fault of the code: a traceback, not exit 2."""
    from seqrank.dirs import check_folder
    from seqrank.rewardbench.bench import BenchSettings, RewardNet
    from seqrank.rewardbench.grid import open_grid
    from seqrank.rewardbench.pool import load_pool

    try:
        for path in args.pool:  # each pool checked before anything is made
            _check_segment_length(load_pool(path), path, args.segment_length)
        check_folder(args.out, "--out")
        _check_scripted(args.teachers)
        settings = BenchSettings(
            tuple(args.budgets),
            args.session_questions,
            segment_length=args.segment_length,
            heldout_segments=args.heldout_segments,
            net=RewardNet(epochs=args.reward_epochs),
            window_steps=args.window_steps,
            overlap_until=args.overlap_until,
            closure_checks=bool(args.closure_checks),
        )
        grid = open_grid(args.pool, settings, args.out)
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    with Progress(
        TextColumn("[bold]cells"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=err,
    ) as progress:
        bar = progress.add_task("cells", total=None)
        started = time.monotonic()

        def report(done: int, total: int) -> None:
            progress.update(bar, completed=done, total=total)
            if not err.is_terminal:  # piped output (logs) gets no live bar: a line a cell
                elapsed = time.monotonic() - started
                err.print(f"cells {done}/{total} ({elapsed / 60:.1f} min)", highlight=False)

        rows = grid.run(
            args.schemes,
            args.teachers,
            list(range(args.seeds)),
            args.workers,
            report,
            learners=args.learners,
            augments=args.augments,
            weightings=args.weightings,
            stops=args.stops,
            orders=args.orders,
        )
    try:
        write_report(rows, args.out, "plain", out)
    except ValueError as problem:  # two rows of one cell (a folder merged by hand)
        raise UsageError(f"{args.out}: {problem}") from None
    return 0


def _check_recorded_task(source: ReplaySource, task: str) -> None:
    """Labels are scored on a pool of the task they were recorded on (any spelling of it)."""
    from seqrank.envs import canonical_task

    recorded = source.labels.header.get("task")
    if recorded is not None and canonical_task(recorded) != canonical_task(task):
        raise ValueError(f"label file {source.source} was recorded on {recorded}, not {task}")


def run_score(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.feedback.replay import ReplaySource
    from seqrank.rewardbench.bench import BenchSettings, run_cell
    from seqrank.rewardbench.cells import Cell
    from seqrank.rewardbench.pool import load_pool

    try:  # the input's checks; scoring itself is the code's (a fault is a traceback)
        pool = load_pool(args.pool)
        source = ReplaySource.from_file(args.labels)
        _check_recorded_task(source, pool.task)
        source.check_compatible(pool.task, pool.obs.shape[2], pool.action.shape[2])
        # one budget per recorded session, so every session's labels are scored
        sizes = _session_sizes(source)
        budgets = tuple(int(sum(sizes[: k + 1])) for k in range(len(sizes)))
        settings = BenchSettings(budgets, max(sizes))
        scheme = source.labels.answers[0]["scheme"]
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    rows = run_cell(pool, Cell(scheme, "replay", args.seed), settings, source)
    for row in rows:
        wrong = "-" if row["inferred_wrong"] is None else f"{row['inferred_wrong']:.3f}"
        out.print(
            f"{row['questions']:>5} answers, {row['pairs']:>5} pairs: accuracy "
            f"{row['accuracy']:.3f}, Spearman {row['spearman']:.3f}, wrong inferred {wrong}",
            highlight=False,
        )
    return 0


def _session_sizes(source: Any) -> list[int]:
    counts: dict[tuple[str, int], int] = {}
    for answer in source.labels.answers:
        key = (answer["run"], answer["session"])
        counts[key] = counts.get(key, 0) + 1
    return [counts[key] for key in source.sessions]
