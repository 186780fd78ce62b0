"""Running the benchmark's grid: pools x teachers x seeds x schemes x learners (and the
other axes of `cells.AXES`), cells in parallel
processes, each finished cell's rows appended to `rows.jsonl` at once, so a killed grid
continues where it stopped and never repeats a finished cell."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass
from itertools import product
from pathlib import Path
from typing import Any

from seqrank.rewardbench.bench import BenchSettings, RewardNet, run_cell
from seqrank.rewardbench.cells import Cell, row_key
from seqrank.rewardbench.pool import Pool, load_pool
from seqrank.rewardbench.windows import checked_windows
from seqrank.rows import read_rows

Progress = Callable[[int, int], None]  # cells done, cells in all


def settings_record(settings: BenchSettings) -> dict[str, Any]:
    return json.loads(json.dumps(asdict(settings)))


def settings_from_record(record: dict[str, Any]) -> BenchSettings:
    net = RewardNet(**record.pop("net"))
    return BenchSettings(**{**record, "budgets": tuple(record["budgets"]), "net": net})


def _check_settings(out: Path, settings: BenchSettings) -> None:
    """A folder holds one grid's settings: continuing it with others would mix results."""
    path, record = out / "settings.json", settings_record(settings)
    if path.exists():
        # a setting added since the folder was made stands at its default (the old behaviour)
        saved = {**settings_record(BenchSettings()), **json.loads(path.read_text())}
        if saved != record:
            changed = sorted(k for k in record if saved.get(k) != record[k])
            raise ValueError(
                f"{out} holds a grid with other settings ({', '.join(changed)} differ); "
                "use another --out or the same settings"
            )


def _checked_pools(out: Path, tasks: dict[str, str]) -> dict[str, dict[str, str]]:
    """A folder's rows of a task come from one pool, known by its content's hash
    (`pools.json`): rows are keyed by task, so a second pool would be taken for done.
    Returns what `pools.json` is to hold."""
    path = out / "pools.json"
    saved: dict[str, dict[str, str]] = json.loads(path.read_text()) if path.exists() else {}
    given: dict[str, dict[str, str]] = {}
    for pool, task in tasks.items():
        record = {"file": pool, "sha256": _file_hash(Path(pool))}
        if task in given and given[task]["sha256"] != record["sha256"]:
            raise ValueError(f"--pool {given[task]['file']} and {pool}: one pool per task")
        known = saved.get(task)
        if known is not None and known["sha256"] != record["sha256"]:
            raise ValueError(
                f"{out} holds {task} rows of another pool ({known['file']} then, not the "
                f"content of {pool}); use another --out for this pool"
            )
        given[task] = record
    return {**saved, **given}


def _file_hash(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _cell_rows(pool_path: str, cell: Cell, record: dict[str, Any]) -> list[dict[str, Any]]:
    import torch

    torch.set_num_threads(1)  # one core per cell: the cells run side by side
    rows = run_cell(load_pool(pool_path), cell, settings_from_record(dict(record)))
    return [{**row, "pool": pool_path} for row in rows]


@dataclass(frozen=True)
class Grid:
    """A grid folder whose pools and settings were checked (`open_grid`): what is left to
    run can only fail by a fault of the code, not of the input."""

    out: Path
    tasks: dict[str, str]  # pool file -> its task
    settings: BenchSettings

    def run(
        self,
        schemes: Sequence[str],
        teachers: Sequence[str],
        seeds: Sequence[int],
        workers: int,
        progress: Progress | None = None,
        learners: Sequence[str] = ("plain",),
        augments: Sequence[str] = ("full",),
        weightings: Sequence[str] = ("reliability",),
        stops: Sequence[str] = ("all",),
        orders: Sequence[str] = ("uniform",),
    ) -> list[dict[str, Any]]:
        """Every cell not in `out/rows.jsonl` yet; returns all rows of the grid."""
        rows_path = self.out / "rows.jsonl"
        rows = read_rows(rows_path)
        rows_path.write_text("".join(json.dumps(r) + "\n" for r in rows))  # drop a cut line
        done = {row_key(r) for r in rows}
        # seed by seed: a grid stopped part way leaves every combination with the same seeds
        todo: dict[tuple[Any, ...], tuple[str, Cell]] = {}  # a cell once, whatever weighs it
        axes = (learners, augments, stops, orders, weightings)
        for seed, path, teacher, *controls, scheme in product(
            seeds, self.tasks, teachers, *axes, schemes
        ):
            learner, augment, stop, order, weighting = controls
            cell = Cell(scheme, teacher, seed, learner, augment, weighting, stop, order)
            if (key := cell.key(self.tasks[path])) not in done:
                todo.setdefault(key, (path, cell))
        total, finished = len(todo) + len(done), len(done)
        if progress is not None:
            progress(finished, total)
        record = settings_record(self.settings)
        with ProcessPoolExecutor(max(1, workers)) as executor:
            running: set[Future[list[dict[str, Any]]]] = {
                executor.submit(_cell_rows, path, cell, record) for path, cell in todo.values()
            }
            while running:
                complete, running = wait(running, return_when=FIRST_COMPLETED)
                for future in complete:
                    new = future.result()
                    with rows_path.open("a") as handle:
                        handle.write("".join(json.dumps(r) + "\n" for r in new))
                    rows.extend(new)
                    finished += 1
                    if progress is not None:
                        progress(finished, total)
        return rows


def open_grid(pools: list[Path], settings: BenchSettings, out: Path) -> Grid:
    """The grid folder `out` for these pools and settings, made or continued. A ValueError
    names a pool that cannot be used, or a folder of other settings or pools; nothing is
    written until every check has passed."""
    tasks = {}
    for path in pools:
        pool = load_pool(path)
        _check_windows(pool, path, settings)
        tasks[str(path)] = pool.task
    _check_settings(out, settings)
    pools_record = _checked_pools(out, tasks)
    out.mkdir(parents=True, exist_ok=True)
    (out / "settings.json").write_text(json.dumps(settings_record(settings), indent=2) + "\n")
    (out / "pools.json").write_text(json.dumps(pools_record, indent=2) + "\n")
    return Grid(out, tasks, settings)


def _check_windows(pool: Pool, path: Path, settings: BenchSettings) -> None:
    """Under `window_steps`, a pool with a window for every session and one to score on."""
    if settings.window_steps is None:
        return
    try:
        checked_windows(pool, settings.window_steps, settings.budgets, settings.session_questions)
    except ValueError as problem:
        raise ValueError(f"pool {path}: {problem}") from None


def run_grid(
    pools: list[Path],
    schemes: list[str],
    teachers: list[str],
    seeds: list[int],
    settings: BenchSettings,
    out: Path,
    workers: int,
    progress: Progress | None = None,
    learners: Sequence[str] = ("plain",),
    augments: Sequence[str] = ("full",),
    stops: Sequence[str] = ("all",),
    orders: Sequence[str] = ("uniform",),
) -> list[dict[str, Any]]:
    """`open_grid` then `Grid.run`: every cell not in `out/rows.jsonl` yet."""
    grid = open_grid(pools, settings, out)
    axes = {"learners": learners, "augments": augments, "stops": stops, "orders": orders}
    return grid.run(schemes, teachers, seeds, workers, progress, **axes)
