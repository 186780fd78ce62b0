"""The offline grid (issue 47, item 5): datasets made, IQL runs on them, a report, each
step skipped when done and continued when interrupted.

A grid file (TOML) names the tasks, the seeds, the question budgets, the schemes and
whether the true reward runs beside them; `[dataset]` says how each task's dataset is made
and `[offline]` holds `seqrank offline train`'s settings for every run:

    tasks = ["dial-turn"]
    seeds = 5                      # 0 .. 4
    questions = [500, 1000]
    schemes = ["pairwise", "sequential", "root", "ranked"]
    true_reward = true             # the ceiling: IQL on the dataset's own reward
    [dataset]                      # played by `seqrank dataset make`:
    sources = ["scripted:0.6", "scripted:1.0", "random"]
    episodes = 600
    # or medium-replay in LiRE's sense, every episode of true-reward SAC runs
    # (`seqrank train --reward true`) of run_steps steps each:
    # runs = 3, run_steps = 100000, run_settings = { scale = "small" }
    [offline]
    steps = 30000
    segment_length = 25

Under `--out`: `sac/<task>/seed<k>` (the SAC runs), `datasets/<task>` (the datasets),
`runs/<task>/<arm>_seed<s>` (an arm is `true` or `<scheme>-q<questions>`), and
`report.md` / `report.json`: per task, budget and arm, the success rate and the return
over seeds (a run's score: the mean of its last `score_last` evaluations, 1 by default):
mean and IQM, each with a 95% percentile bootstrap interval over seeds.

`--keep DIR` makes a grid outlive its machine: each IQL run's records (its config, metrics
and summary, not its checkpoint) are copied to `DIR/<task>/<run>` as it finishes (or when a
finished run is found that DIR lacks), and the runs found there count as finished: their
records are copied back under `--out` first, at every stage. Commit DIR, and the grid
continues on a new machine where it stopped. The report says when a task's runs trained on
datasets of different digests (a dataset made again elsewhere that came out otherwise).

A finished step (a SAC run's or an IQL run's summary.json, a dataset's folder) is
skipped; a stopped one continues from its last checkpoint (`seqrank train --resume`;
`seqrank.offline_train` continues a folder of the same settings). `--shard I/N` runs every
N-th IQL run from the I-th (start the datasets first, `--stage datasets`, then one process
a shard); `--stage report` only writes the report.

    python scripts/offline_grid.py results/offline-metaworld/grid.toml --out offline-grid \
        --keep results/offline-metaworld/runs
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
import tomllib
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.offline.settings import LEARNED_ONLY

GRID_KEYS = {"tasks", "seeds", "questions", "schemes", "true_reward", "score_last",
             "dataset", "offline"}  # fmt: skip
DATASET_KEYS = {"runs", "run_steps", "run_settings", "sources", "episodes", "seed"}
BOOTSTRAP = 10_000  # resamples of each interval
RECORDS = ("config.json", "meta.json", "metrics.jsonl", "summary.json")  # what --keep keeps


@dataclass(frozen=True)
class Grid:
    tasks: list[str]
    seeds: list[int]
    questions: list[int]
    schemes: list[str]
    true_reward: bool
    score_last: int
    dataset: dict[str, Any]
    offline: dict[str, Any]

    @classmethod
    def read(cls, path: Path) -> Grid:
        values = tomllib.loads(Path(path).read_text())
        unknown = sorted(set(values) - GRID_KEYS)
        if unknown:
            raise ValueError(f"{path}: unknown key {unknown[0]!r}; known: {sorted(GRID_KEYS)}")
        dataset = dict(values.get("dataset", {}))
        unknown = sorted(set(dataset) - DATASET_KEYS)
        if unknown:
            raise ValueError(f"{path}: unknown [dataset] key {unknown[0]!r}")
        if ("runs" in dataset) == ("sources" in dataset):
            raise ValueError(f"{path}: [dataset] takes runs (SAC runs) or sources, one of them")
        seeds = values.get("seeds", 5)
        return cls(
            tasks=list(values["tasks"]),
            seeds=list(range(seeds)) if isinstance(seeds, int) else list(seeds),
            questions=list(values.get("questions", [500, 1000])),
            schemes=list(values.get("schemes", ["pairwise", "sequential", "root", "ranked"])),
            true_reward=bool(values.get("true_reward", True)),
            score_last=int(values.get("score_last", 1)),
            dataset=dataset,
            offline=dict(values.get("offline", {})),
        )

    def arms(self) -> list[tuple[str, dict[str, Any]]]:
        """(name, the run's reward settings) of every arm, the true reward first."""
        arms: list[tuple[str, dict[str, Any]]] = []
        if self.true_reward:
            arms.append(("true", {"reward": "true"}))
        for questions in self.questions:
            for scheme in self.schemes:
                settings = {"reward": "learned", "scheme": scheme, "max_feedback": questions}
                arms.append((f"{scheme}-q{questions}", settings))
        return arms


@dataclass
class Layout:
    out: Path

    def sac(self, task: str, seed: int) -> Path:
        return self.out / "sac" / slug(task) / f"seed{seed}"

    def dataset(self, task: str) -> Path:
        return self.out / "datasets" / slug(task)

    def run(self, task: str, arm: str, seed: int) -> Path:
        return self.out / "runs" / slug(task) / f"{arm}_seed{seed}"


def slug(task: str) -> str:
    return task.replace(":", "-").replace("/", "-")


@dataclass
class Progress:
    done: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    say: Callable[[str], None] = print

    def step(self, what: str, work: Callable[[], Any]) -> bool:
        """Run one step; a failure is reported and counted, and the grid goes on."""
        started = time.perf_counter()
        self.say(f"{what} ...")
        try:
            work()
        except Exception:  # one run's failure must not stop the grid
            self.failed.append(what)
            self.say(f"FAILED {what}:\n{traceback.format_exc()}")
            return False
        self.done.append(what)
        self.say(f"done {what} ({time.perf_counter() - started:.0f} s)")
        return True


def finished(run: Path) -> bool:
    return (run / "summary.json").is_file()


def sac_argv(grid: Grid, layout: Layout, task: str, seed: int) -> list[str]:
    """`seqrank train`'s arguments for one SAC run of the dataset (or its continuation)."""
    run = layout.sac(task, seed)
    if (run / "config.json").is_file():
        return ["train", "--resume", str(run)]
    steps = int(grid.dataset["run_steps"])
    argv = ["train", "--task", task, "--reward", "true", "--steps", str(steps),
            "--seed", str(seed), "--out", str(run),
            "--episodes-kept", str(episodes_in(task, steps))]  # fmt: skip
    for name, value in grid.dataset.get("run_settings", {}).items():
        argv += [f"--{name.replace('_', '-')}", str(value)]
    return argv


def episodes_in(task: str, steps: int) -> int:
    """Episodes a run of `steps` steps plays (at least): all of them are kept."""
    from seqrank.envs import make_env

    env = make_env(task)
    try:
        return -(-steps // env.episode_length)
    finally:
        env.close()


def dataset_argv(grid: Grid, layout: Layout, task: str) -> list[str]:
    argv = ["dataset", "make", "--task", task, "--out", str(layout.dataset(task))]
    if "runs" in grid.dataset:
        runs = range(int(grid.dataset["runs"]))
        for seed in runs:
            argv += ["--source", f"run:{layout.sac(task, seed)}"]
        per_run = episodes_in(task, int(grid.dataset["run_steps"]))
        return [*argv, "--episodes", str(per_run * len(runs))]
    for source in grid.dataset["sources"]:
        argv += ["--source", source]
    argv += ["--episodes", str(grid.dataset["episodes"])]
    return [*argv, "--seed", str(grid.dataset.get("seed", 0))]


def cli(argv: list[str]) -> None:
    from seqrank.cli import main

    code = main(argv)
    if code:
        raise RuntimeError(f"seqrank {' '.join(argv)} ended with {code}")


def make_datasets(grid: Grid, layout: Layout, progress: Progress) -> None:
    for task in grid.tasks:
        if layout.dataset(task).is_dir():
            continue
        if "runs" in grid.dataset:
            for seed in range(int(grid.dataset["runs"])):
                run = layout.sac(task, seed)
                if not finished(run):
                    argv = sac_argv(grid, layout, task, seed)
                    progress.step(f"SAC {task} seed {seed}", partial(cli, argv))
            if not all(finished(layout.sac(task, s)) for s in range(int(grid.dataset["runs"]))):
                continue
        argv = dataset_argv(grid, layout, task)
        progress.step(f"dataset {task}", partial(cli, argv))


def offline_jobs(grid: Grid, layout: Layout) -> Iterator[tuple[str, Path, Path, dict[str, Any]]]:
    """(name, dataset, run directory, settings) of every IQL run, seed-major so that an
    unfinished grid holds whole seeds of every arm."""
    for seed in grid.seeds:
        for task in grid.tasks:
            for arm, reward in grid.arms():
                settings = {**grid.offline, **reward, "seed": seed, "task": task}
                if settings.get("reward", "true") == "true":  # (it asks no question)
                    settings = {k: v for k, v in settings.items() if k not in LEARNED_ONLY}
                name = f"IQL {task} {arm} seed {seed}"
                yield name, layout.dataset(task), layout.run(task, arm, seed), settings


def run_offline(
    grid: Grid, layout: Layout, progress: Progress, shard: tuple[int, int], keep: Path | None
) -> None:
    import seqrank

    index, count = shard
    for position, (name, dataset, run, settings) in enumerate(offline_jobs(grid, layout)):
        if position % count != index:
            continue
        kept = None if keep is None else keep / run.relative_to(layout.out / "runs")
        if finished(run):
            if kept is not None and not finished(kept):  # finished before --keep was given
                copy_records(run, kept)
            continue
        if not dataset.is_dir():
            progress.say(f"skipped {name}: its dataset {dataset} is not made yet")
            continue
        run.parent.mkdir(parents=True, exist_ok=True)
        work = partial(seqrank.offline_train, str(dataset), run, **settings)
        if progress.step(name, work) and kept is not None:
            copy_records(run, kept)


def copy_records(source: Path, target: Path) -> None:
    """A finished run's records (not its checkpoint), from `source` into `target`."""
    target.mkdir(parents=True, exist_ok=True)
    for name in RECORDS:
        if (source / name).is_file():
            shutil.copy2(source / name, target / name)


def restore_kept(keep: Path, layout: Layout) -> int:
    """Kept runs that `--out` lacks, copied back there; returns how many."""
    restored = 0
    for summary in sorted(keep.glob("*/*/summary.json")):
        run = layout.out / "runs" / summary.parent.relative_to(keep)
        if not finished(run):
            copy_records(summary.parent, run)
            restored += 1
    return restored


def run_score(summary: dict[str, Any], curve: str, last: int) -> float | None:
    points = summary.get(curve) or []
    if not points:
        return None
    return float(np.mean([value for _, value in points[-last:]]))


def bootstrap(values: list[float], statistic: Callable[[np.ndarray], float]) -> list[float]:
    """The statistic and its 95% percentile bootstrap interval over `values` (seeds)."""
    array = np.asarray(values, np.float64)
    if len(array) < 2:
        return [statistic(array)] * 3
    rng = np.random.default_rng(0)
    draws = rng.integers(len(array), size=(BOOTSTRAP, len(array)))
    resampled = np.array([statistic(array[row]) for row in draws])
    low, high = np.percentile(resampled, [2.5, 97.5])
    return [statistic(array), float(low), float(high)]


def collect(grid: Grid, layout: Layout) -> dict[str, Any]:
    from seqrank.report.stats import iqm

    rows, missing, digests = [], [], {}
    for task in grid.tasks:
        seen: set[str] = set()
        for arm, _ in grid.arms():
            scores: dict[str, list[float]] = {"success": [], "return": []}
            seeds = []
            for seed in grid.seeds:
                path = layout.run(task, arm, seed) / "summary.json"
                if not path.is_file():
                    missing.append(str(path.parent.relative_to(layout.out)))
                    continue
                summary = json.loads(path.read_text())
                seen.add(str(summary.get("dataset_digest")))
                seeds.append(seed)
                for key, curve in (("success", "success_curve"), ("return", "eval_curve")):
                    value = run_score(summary, curve, grid.score_last)
                    if value is not None:
                        scores[key].append(value)
            row: dict[str, Any] = {"task": task, "arm": arm, "seeds": seeds}
            for key, values in scores.items():
                if values:
                    row[key] = {"values": values,
                                "mean": bootstrap(values, lambda a: float(a.mean())),
                                "iqm": bootstrap(values, iqm)}  # fmt: skip
            rows.append(row)
        digests[task] = sorted(seen)
    return {"score_last": grid.score_last, "rows": rows, "missing": missing, "digests": digests}


def markdown(report: dict[str, Any]) -> str:
    def cell(entry: dict[str, Any] | None, key: str) -> str:
        if not entry:
            return "-"
        value, low, high = entry[key]
        return f"{value:.1f} [{low:.1f}, {high:.1f}]"

    lines = [
        "| task | arm | seeds | success mean [95% CI] | success IQM [95% CI] "
        "| return mean [95% CI] | return IQM [95% CI] |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in report["rows"]:
        success, returns = row.get("success"), row.get("return")
        lines.append(
            f"| {row['task']} | {row['arm']} | {len(row['seeds'])} | {cell(success, 'mean')} "
            f"| {cell(success, 'iqm')} | {cell(returns, 'mean')} | {cell(returns, 'iqm')} |"
        )
    last = report["score_last"]
    lines += [
        "",
        f"A run's score: the mean of its last {last} evaluation(s). Intervals: 95% "
        f"percentile bootstrap over seeds ({BOOTSTRAP} resamples).",
    ]
    for task, seen in report["digests"].items():
        if len(seen) > 1:
            lines += [
                "",
                f"**{task}: its runs trained on {len(seen)} different datasets "
                f"(digests {', '.join(seen)}); its arms are not comparable.**",
            ]
    if report["missing"]:
        lines += ["", f"Not finished yet: {len(report['missing'])} runs."]
    return "\n".join(lines) + "\n"


def write_report(grid: Grid, layout: Layout) -> dict[str, Any]:
    report = collect(grid, layout)
    layout.out.mkdir(parents=True, exist_ok=True)
    (layout.out / "report.json").write_text(json.dumps(report, indent=1) + "\n")
    (layout.out / "report.md").write_text(markdown(report))
    return report


def parse_shard(text: str) -> tuple[int, int]:
    index, _, count = text.partition("/")
    shard = (int(index), int(count))
    if not 0 <= shard[0] < shard[1]:
        raise argparse.ArgumentTypeError(f"--shard I/N needs 0 <= I < N, got {text}")
    return shard


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("grid", type=Path, help="the grid file (TOML)")
    parser.add_argument("--out", type=Path, required=True, help="the grid's folder")
    parser.add_argument("--stage", choices=("all", "datasets", "runs", "report"), default="all")
    parser.add_argument("--shard", type=parse_shard, default=(0, 1), help="I/N (0/1)")
    parser.add_argument("--keep", type=Path, help="where finished runs' records are kept")
    args = parser.parse_args(argv)
    grid, layout = Grid.read(args.grid), Layout(args.out)
    progress = Progress(say=lambda line: print(line, flush=True))
    if args.keep is not None and (restored := restore_kept(args.keep, layout)):
        progress.say(f"{restored} finished runs' records restored from {args.keep}")
    try:
        if args.stage in ("all", "datasets"):
            make_datasets(grid, layout, progress)
        if args.stage in ("all", "runs"):
            run_offline(grid, layout, progress, args.shard, args.keep)
    except KeyboardInterrupt:  # a stop asked for, not a failure: no traceback
        print(f"stopped after {len(progress.done)} step(s); the same command continues the grid")
        return 130
    report = write_report(grid, layout)
    print(markdown(report), end="")
    if progress.failed:
        print(f"{len(progress.failed)} step(s) failed: {', '.join(progress.failed)}")
    return 1 if progress.failed else 0


if __name__ == "__main__":
    sys.exit(main())
