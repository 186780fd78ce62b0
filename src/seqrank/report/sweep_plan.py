"""A sweep's folder holds runs that its plan no longer names: a baseline that an earlier
version planned once per variant (`<method>_<variant>_seed<seed>`) is now planned once per
task and seed (`<method>_seed<seed>`). The sweep takes one such directory over (renames it)
or, when its settings differ, runs the baseline again; the other directories stay. The
report counts the run the sweep plans, and names the ones left from earlier versions
rather than counting a seed of a baseline twice (once under each name).

The plan is the run names in the sweep's `sweep.json`, beside the `runs` folder reported.
"""

from __future__ import annotations

import json
from pathlib import Path

from seqrank.report.collect import RunResult

STATE_FILE = "sweep.json"  # `sweeps.runner` writes it to the sweep's `out`
RUNS = "runs"  # the sweep's run directories, `<out>/runs/<task>/<name>`


def planned_runs(folder: Path) -> set[Path] | None:
    """The directories of the runs a sweep plans, when `folder` is a sweep's `out` or its
    `runs` folder (None for a folder of runs made by hand)."""
    out = folder.parent if folder.name == RUNS else folder
    state = out / STATE_FILE
    if not state.is_file():
        return None
    try:
        names = [run["name"] for run in json.loads(state.read_text())["runs"]]
    except (json.JSONDecodeError, KeyError, TypeError):
        return None  # not a sweep's state: report every run
    return {(out / RUNS / name).resolve() for name in names}


def without_earlier_baselines(
    runs: list[RunResult], folder: Path
) -> tuple[list[RunResult], list[str]]:
    """The runs less the baselines an earlier version of the sweep made under another name
    where the plan has its own run of that task, baseline and seed; a note naming them."""
    planned = planned_runs(folder)
    if planned is None:
        return runs, []
    in_plan = {
        (r.task, r.reward, r.seed) for r in runs if r.baseline and r.path.resolve() in planned
    }
    earlier = [
        r
        for r in runs
        if r.baseline and r.path.resolve() not in planned and (r.task, r.reward, r.seed) in in_plan
    ]
    if not earlier:
        return runs, []
    names = ", ".join(sorted(str(r.path.relative_to(folder)) for r in earlier))
    note = (
        f"left out {names}: baseline runs an earlier version of the sweep made under another "
        "name, which it now plans and runs under its own"
    )
    left_out = {r.path for r in earlier}
    return [r for r in runs if r.path not in left_out], [note]
