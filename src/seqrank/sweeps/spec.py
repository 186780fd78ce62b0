"""Sweep files: a grid of training runs in TOML.

```toml
name = "walker-pebble"            # optional; names the output folder
out = "seqrank-out/sweeps/walker" # optional; default seqrank-out/sweeps/<name>
scale = "small"                   # optional: auto (default), paper, small
device = "cpu"                    # optional: auto (default), cpu, cuda
tasks = ["walker_walk", "cheetah_run"]
schemes = ["pairwise", "sequential", "root"]
backbones = ["pebble"]            # optional, default ["pebble"]
teachers = ["oracle"]             # optional, default ["oracle"]
baselines = ["true", "none"]      # optional: the true-reward agent, the no-feedback floor
seeds = 3                         # a count (0, 1, 2) or a list [0, 5, 7]
retries = 1                       # optional: attempts after a failure, default 1
wandb = "my-project"              # optional: every run also logs to this W&B project

[overrides]                       # any `seqrank train` setting, for every run
steps = 100000

[task_overrides.cheetah_run]      # settings for one task's runs
max_feedback = 200

[[variants]]                      # optional extra axis: named groups of settings
name = "q100"
max_feedback = 100
```

Every run is one `seqrank train` run directory: `<out>/runs/<task>/<scheme>_<backbone>_
<teacher>[_<variant>]_seed<seed>`; a baseline run (one per task and seed, whatever the
schemes, backbones and teachers) is `<task>/<true-reward|no-feedback>_seed<seed>`, and
`schemes` may be left out when `baselines` is given. A baseline leaves out the settings
that never reach it (`config.unread_settings`: the feedback settings; for the true-reward
agent pre-training and the reward model too), so variants that change only those share
it; a variant that changes what it uses gets its own, `<task>/<method>_<variant>_seed<seed>`
(of those that come out alike the first is kept). Settings of one run: [overrides] <
[task_overrides.<task>] < its variant < its axes. Expansion checks every run's settings
up front, so a bad value is reported before anything starts.
"""

from __future__ import annotations

import json
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass, fields, replace
from itertools import product
from pathlib import Path
from typing import Any

from seqrank.choices import RewardSignal
from seqrank.config import TrainConfig, resolve_config, unread_settings

TOP_KEYS = (
    "name",
    "out",
    "scale",
    "device",
    "tasks",
    "schemes",
    "backbones",
    "teachers",
    "baselines",
    "seeds",
    "retries",
    "wandb",
    "overrides",
    "task_overrides",
    "variants",
)
AXES = {"tasks": "task", "schemes": "scheme", "backbones": "backbone", "teachers": "teacher"}
AXIS_SETTINGS = {"task", "scheme", "backbone", "teacher", "reward", "seed"}
SETTINGS = {f.name for f in fields(TrainConfig)} - AXIS_SETTINGS - {"device"}
# int and float settings, and the rest given as strings (choices are checked by the config)
_KIND = {f.name: str(f.type) if f.type in ("int", "float") else "str" for f in fields(TrainConfig)}


@dataclass(frozen=True)
class PlannedRun:
    name: str  # relative path under <out>/runs
    config: TrainConfig
    wandb: str | None = None  # a W&B project that also gets the run's metrics
    # names earlier versions gave this run: a baseline was once planned under each
    # variant's name (`sweeps.folder.earlier_runs` takes such a directory over)
    former: tuple[str, ...] = ()


@dataclass(frozen=True)
class Sweep:
    name: str
    out: Path
    runs: tuple[PlannedRun, ...]
    retries: int
    device: str


def load_sweep(path: Path) -> Sweep:
    """Parse and expand a sweep file; ValueError names the file, the key and what is accepted."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"sweep file {path} does not exist")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{path}: not valid TOML ({error})") from None
    return expand(data, str(path))


def expand(data: dict[str, Any], source: str = "<sweep>") -> Sweep:
    unknown = sorted(set(data) - set(TOP_KEYS))
    if unknown:
        raise ValueError(f"{source}: unknown key {unknown[0]!r}; accepted: {', '.join(TOP_KEYS)}")
    baselines = _baselines(data.get("baselines", []), source)
    if baselines and "schemes" not in data:
        if "teachers" in data:  # they would teach nothing: no learned run is planned
            raise ValueError(
                f"{source}: teachers are given but no schemes, so only the baselines would "
                "run; give schemes (for a replay teacher, the scheme its label file recorded)"
            )
        data = {**data, "schemes": []}
    axes = {key: _names(data, key, source) for key in AXES}
    seeds = _seeds(data.get("seeds", 1), source)
    retries = data.get("retries", 1)
    if not isinstance(retries, int) or retries < 0:
        raise ValueError(f"{source}: retries must be a whole number >= 0, got {retries!r}")
    scale = data.get("scale", "auto")
    if scale not in ("auto", "paper", "small"):
        raise ValueError(f"{source}: scale {scale!r}; accepted: auto, paper, small")
    device = data.get("device", "auto")
    wandb = data.get("wandb")
    if wandb is not None and (not isinstance(wandb, str) or not wandb.strip()):
        raise ValueError(f"{source}: wandb must be a project name, got {wandb!r}")
    overrides = _settings(data.get("overrides", {}), f"{source} [overrides]")
    per_task = data.get("task_overrides", {})
    if not isinstance(per_task, dict):
        raise ValueError(f"{source}: task_overrides must be a table of tables")
    strays = sorted(set(per_task) - set(axes["tasks"]))
    if strays:
        raise ValueError(f"{source}: task_overrides.{strays[0]} names a task not in tasks")
    variants = _variants(data.get("variants", []), source)
    if scale == "auto":
        from seqrank.scale import resolve_scale
        from seqrank.training.runtime import resolve_device

        scale = resolve_scale(scale, resolve_device(device))
    methods = _methods(axes, baselines)
    # seed by seed: a sweep stopped part way leaves every method with the same seeds done
    grid = product(seeds, axes["tasks"], methods, variants)
    planned = _Planned(source, scale, device, wandb, overrides, per_task)
    runs = _once(planned.run(task, method, variant, seed) for seed, task, method, variant in grid)
    name = str(data.get("name", Path(source).stem))
    out = Path(data.get("out", Path("seqrank-out/sweeps") / name))
    return Sweep(name, out, tuple(runs), retries, device)


def _once(runs: Iterable[PlannedRun]) -> list[PlannedRun]:
    """The runs, less a baseline run planned already: one of the same name (variants that
    change nothing it uses), or of the same settings (variants that change them alike);
    the run kept takes over the names the dropped one once had."""
    kept: dict[str, PlannedRun] = {}
    by_settings: dict[str, str] = {}
    for run in runs:
        key = json.dumps(run.config.as_dict(), sort_keys=True, default=str)
        first = run.name if run.name in kept else by_settings.get(key)
        if run.config.reward.asks or first is None:
            kept[run.name] = run
            by_settings.setdefault(key, run.name)
        else:
            earlier = kept[first]
            names = (n for n in (*earlier.former, *run.former) if n != first)
            kept[first] = replace(earlier, former=tuple(dict.fromkeys(names)))
    return list(kept.values())


Method = tuple[str, dict[str, str]]  # a run name's method part, and its axis settings


def _methods(axes: dict[str, list[str]], baselines: list[RewardSignal]) -> list[Method]:
    learned = product(axes["schemes"], axes["backbones"], axes["teachers"])
    methods = [(f"{s}_{b}_{t}", {"scheme": s, "backbone": b, "teacher": t}) for s, b, t in learned]
    return methods + [(b.method, {"reward": b.value}) for b in baselines]


@dataclass(frozen=True)
class _Planned:
    """What every run of a sweep shares; `run` checks and names one of them."""

    source: str
    scale: str
    device: str
    wandb: str | None
    overrides: dict[str, Any]
    per_task: dict[str, Any]

    def run(
        self, task: str, method: Method, variant: tuple[str | None, dict[str, Any]], seed: int
    ) -> PlannedRun:
        (name, axis_values), (variant_name, extra) = method, variant
        settings = {
            **self.overrides,
            **_settings(self.per_task.get(task, {}), f"{self.source} [task_overrides.{task}]"),
            **extra,
            **axis_values,
            "seed": seed,
            "device": self.device,
        }
        suffix = f"_{variant_name}" if variant_name else ""
        former: tuple[str, ...] = ()
        if "reward" in axis_values:  # a baseline: it asks nothing
            unused = baseline_unused(RewardSignal(axis_values["reward"]), settings)
            settings = {k: v for k, v in settings.items() if k not in unused}
            if not set(extra) - unused:  # the variant changes nothing this run uses
                former, suffix = (suffix,) if suffix else (), ""
        shown = " ".join(part for part in (task, name, variant_name) if part)
        where = f"{self.source}: run {shown} seed {seed}"
        try:
            config = resolve_config(task, self.scale, settings)
            if self.device in ("cpu", "cuda"):  # with auto the path depends on where it runs
                _check_path(config, self.device)
        except (ValueError, TypeError) as problem:
            raise ValueError(f"{where}: {problem}") from None
        folder = task.replace(":", "-")
        named = [f"{folder}/{name}{part}_seed{seed}" for part in (suffix, *former)]
        return PlannedRun(named[0], config, self.wandb, tuple(named[1:]))


def baseline_unused(reward: RewardSignal, settings: dict[str, Any]) -> frozenset[str]:
    """The settings that never reach a baseline run of `reward` with these `settings`."""
    return unread_settings(reward, bool(settings.get("start_from")))


def unused_settings(config: TrainConfig) -> frozenset[str]:
    """The settings that never reach a run of this config: the crowd's where one teacher
    answers, and a baseline's unread ones."""
    from seqrank.config.rules import unread_crowd_settings

    crowd = unread_crowd_settings(config)
    if config.reward.asks:
        return crowd
    return crowd | baseline_unused(config.reward, config.as_dict())


def _check_path(config: TrainConfig, device: str) -> None:
    """A precision that the run's path does not offer on `device` (ValueError)."""
    import torch

    from seqrank.training.runtime import config_runtime

    config_runtime(config, torch.device(device))


def _baselines(value: Any, source: str) -> list[RewardSignal]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ValueError(f'{source}: baselines must be a list of names, e.g. ["true"]')
    accepted = [b.value for b in RewardSignal if not b.asks]
    unknown = [v for v in value if v not in accepted]
    if unknown:
        raise ValueError(
            f"{source}: unknown baseline {unknown[0]!r}; accepted: {', '.join(accepted)}"
        )
    chosen = [RewardSignal(v) for v in value]
    if len(set(chosen)) != len(chosen):
        raise ValueError(f"{source}: baselines lists a name twice: {value!r}")
    return chosen


def _names(data: dict[str, Any], key: str, source: str) -> list[str]:
    defaults = {"backbones": ["pebble"], "teachers": ["oracle"]}
    if key not in data and key not in defaults:
        raise ValueError(f"{source}: {key} is required (a list, e.g. {key} = [...])")
    values = data.get(key, defaults.get(key))
    if key == "schemes" and values == [] and "baselines" in data:
        return []  # a sweep of baselines only
    if not isinstance(values, list) or not values or not all(isinstance(v, str) for v in values):
        raise ValueError(f"{source}: {key} must be a non-empty list of names, got {values!r}")
    if len(set(values)) != len(values):
        raise ValueError(f"{source}: {key} lists a name twice: {values!r}")
    return values


def _seeds(value: Any, source: str) -> list[int]:
    if isinstance(value, bool):
        raise ValueError(f"{source}: seeds must be a count or a list of whole numbers")
    if isinstance(value, int):
        if value < 1:
            raise ValueError(f"{source}: seeds = {value}: a count must be at least 1")
        return list(range(value))
    if (
        isinstance(value, list)
        and value
        and all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in value)
        and len(set(value)) == len(value)
    ):
        return list(value)
    raise ValueError(
        f"{source}: seeds = {value!r}: give a count or a list of distinct whole numbers >= 0"
    )


def _settings(table: Any, where: str) -> dict[str, Any]:
    if not isinstance(table, dict):
        raise ValueError(f"{where}: must be a table of settings")
    unknown = sorted(set(table) - SETTINGS)
    if unknown:
        raise ValueError(
            f"{where}: unknown setting {unknown[0]!r}; settings are `seqrank train` options "
            "(task, scheme, backbone, teacher and seed are sweep axes, reward is set by "
            "`baselines`, device at the top level)"
        )
    for key, value in table.items():
        kind = _KIND[key]
        ok = {
            "int": isinstance(value, int) and not isinstance(value, bool),
            "float": isinstance(value, int | float) and not isinstance(value, bool),
            "str": isinstance(value, str),
        }[kind]
        if not ok:
            raise ValueError(
                f"{where}: {key} = {value!r} is not a{'n' if kind == 'int' else ''} {kind}"
            )
    return dict(table)


def _variants(value: Any, source: str) -> list[tuple[str | None, dict[str, Any]]]:
    if value == []:
        return [(None, {})]
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise ValueError(f"{source}: variants must be a list of tables ([[variants]])")
    out: list[tuple[str | None, dict[str, Any]]] = []
    for k, table in enumerate(value):
        name = table.get("name")
        if not isinstance(name, str) or not name.replace("-", "").replace("_", "").isalnum():
            raise ValueError(f"{source}: variant {k + 1} needs a name of letters, digits, - or _")
        settings = {key: v for key, v in table.items() if key != "name"}
        out.append((name, _settings(settings, f"{source} [[variants]] {name}")))
    names = [n for n, _ in out]
    if len(set(names)) != len(names):
        raise ValueError(f"{source}: two variants are called the same: {names!r}")
    return out
