"""The benchmark plan and its interleaved execution."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import torch

from seqrank.bench.measure import loop_rates, reward_epoch_microseconds, update_microseconds
from seqrank.config import TrainConfig, resolve_config
from seqrank.envs import canonical_task
from seqrank.scale import resolve_scale

KINDS = ("update", "reward", "loop")


@dataclass(frozen=True)
class Variant:
    name: str
    fast: bool
    precision: str


@dataclass(frozen=True)
class BenchPlan:
    config: TrainConfig
    device: torch.device
    variants: tuple[Variant, ...]
    repeats: int
    updates: int
    reward_epochs: int
    loop_steps: int
    full_run: bool

    @classmethod
    def build(
        cls,
        task: str,
        scale: str,
        device: torch.device,
        precisions: list[str],
        overrides: dict[str, Any],
        args: Any,
    ) -> BenchPlan:
        config = resolve_config(
            task, resolve_scale(scale, device), {**overrides, "device": device.type}
        )
        if canonical_task(task)[0] == "block":
            raise ValueError(f"task {task!r} learns with DQN; the benchmark times SAC's paths")
        variants = [Variant("reference", False, "fp32")]
        variants += [Variant(f"fast-{p}", True, p) for p in precisions]
        return cls(
            config,
            device,
            tuple(variants),
            args.repeats,
            args.updates,
            args.reward_epochs,
            args.loop_steps,
            args.full_run,
        )

    @property
    def total_measurements(self) -> int:
        return self.repeats * len(self.variants) * len(KINDS) + int(self.full_run)


def run_bench(plan: BenchPlan, on_measurement: Callable[[str], None]) -> dict[str, Any]:
    """Every kind of measurement, each round running every variant in turn."""
    samples: dict[str, dict[str, list[Any]]] = {
        v.name: {kind: [] for kind in KINDS} for v in plan.variants
    }
    config, device = plan.config, plan.device
    for _ in range(plan.repeats):
        for kind in KINDS:
            for v in plan.variants:
                on_measurement(f"{kind}: {v.name}")
                if kind == "update":
                    value: Any = update_microseconds(
                        config, device, v.fast, v.precision, plan.updates
                    )
                elif kind == "reward":
                    value = reward_epoch_microseconds(
                        config, device, v.fast, v.precision, plan.reward_epochs
                    )
                else:
                    value = loop_rates(config, device, v.fast, v.precision, plan.loop_steps)
                samples[v.name][kind].append(value)
    variants = {v.name: summarise(samples[v.name], config) for v in plan.variants}
    result: dict[str, Any] = {
        "device": device_name(device),
        "torch": torch.__version__,
        "settings": settings_of(plan),
        "variants": variants,
        "ratios": ratios(variants),
    }
    if plan.full_run:
        on_measurement("full run: fast")
        result["full_run"] = full_run(plan)
    return result


def summarise(samples: dict[str, list[Any]], config: TrainConfig) -> dict[str, Any]:
    """Medians over rounds, and the full run projected from them."""
    median = statistics.median
    loop = samples["loop"]
    row = {
        "update_us": median(s["us"] for s in samples["update"]),
        "update_us_rounds": [round(s["us"], 1) for s in samples["update"]],
        "capture_s": max(s["capture_s"] for s in samples["update"]),
        "reward_epoch_us": median(samples["reward"]),
        "loop_steps_per_s": median(s["steps_per_s"] for s in loop),
        "loop_steps_per_s_rounds": [round(s["steps_per_s"], 1) for s in loop],
        "collect_us": median(s["collect_us"] for s in loop),
        "session_s": median(s["session_s"] for s in loop),
        "eval_episode_s": median(s["eval_episode_s"] for s in loop),
    }
    evaluations = config.steps // config.eval_every
    row["projected_full_run_s"] = (
        config.steps / row["loop_steps_per_s"]
        + config.sessions * row["session_s"]
        + evaluations * config.eval_episodes * row["eval_episode_s"]
    )
    return row


def ratios(variants: dict[str, dict[str, Any]]) -> dict[str, dict[str, float]]:
    """How many times faster each fast variant is than the reference (>1: faster)."""
    ref = variants["reference"]
    out = {}
    for name, row in variants.items():
        if name == "reference":
            continue
        out[name] = {
            "update": ref["update_us"] / row["update_us"],
            "reward_epoch": ref["reward_epoch_us"] / row["reward_epoch_us"],
            "loop": row["loop_steps_per_s"] / ref["loop_steps_per_s"],
            "projected_full_run": ref["projected_full_run_s"] / row["projected_full_run_s"],
        }
    return out


def settings_of(plan: BenchPlan) -> dict[str, Any]:
    c = plan.config
    return {
        "task": c.task,
        "scale": c.scale,
        "hidden": c.hidden,
        "layers": c.layers,
        "batch": c.batch,
        "reward_ensemble": c.reward_ensemble,
        "reward_hidden": c.reward_hidden,
        "steps": c.steps,
        "sessions": c.sessions,
        "eval_every": c.eval_every,
        "eval_episodes": c.eval_episodes,
        "repeats": plan.repeats,
        "updates": plan.updates,
        "reward_epochs": plan.reward_epochs,
        "loop_steps": plan.loop_steps,
    }


def device_name(device: torch.device) -> str:
    if device.type == "cuda":
        return torch.cuda.get_device_name(device)
    import platform

    from seqrank.training.cpu_path import training_threads

    threads, fast = torch.get_num_threads(), training_threads(fast=True)
    loop = f"; the fast path's loop, as a run trains: {fast}" if fast != threads else ""
    return f"CPU ({platform.processor() or platform.machine()}, {threads} threads{loop})"


def full_run(plan: BenchPlan) -> dict[str, Any]:
    """The fast path (default precision) for the whole run, timed end to end."""
    import tempfile
    from pathlib import Path

    from seqrank.choices import Precision, TrainingPath
    from seqrank.training.runs import RunDir
    from seqrank.training.trainer import Trainer

    config = replace(plan.config, path=TrainingPath.FAST, precision=Precision.AUTO)
    with tempfile.TemporaryDirectory(prefix="seqrank-bench-") as folder:
        trainer = Trainer(config, RunDir.create(Path(folder) / "run", config, plan.device.type))
        started = time.perf_counter()
        summary = trainer.train()
        seconds = time.perf_counter() - started
    return {
        "steps": config.steps,
        "wall_s": seconds,
        "final_eval_return": summary["final_eval_return"],
        "asked": summary["asked"],
    }
