"""`seqrank bench`: interleaved timings of both paths, written as JSON and Markdown."""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
from dataclasses import fields
from pathlib import Path
from typing import Any

from rich.console import Console

from seqrank.cli.options import field_type, int_between, split_names
from seqrank.config import PRECISIONS, SCALES, TrainConfig
from seqrank.console_tables import progress_bar
from seqrank.errors import UsageError

FAST_PRECISIONS = [p for p in PRECISIONS if p != "auto"]
ABOUT = (
    "Run the reference path (host replay buffer, a host-to-device copy per batch, the reward "
    "model asked per step, strict fp32, a host sync per update) and the fast path (device "
    "buffer, no syncs, CUDA graphs, TF32/bf16) in one process, interleaved, and write "
    "microseconds per SAC update and per reward epoch, loop steps per second, the projected "
    "full-run time and the fast/reference ratios to OUT.json and OUT.md."
)


def add_parser(commands: Any) -> None:
    bench = commands.add_parser(
        "bench", help="time the reference and fast training paths side by side", description=ABOUT
    )
    bench.add_argument(
        "--task", default="walker_walk", help="the task whose shapes are timed (walker_walk)"
    )
    bench.add_argument(
        "--device", choices=("auto", "cpu", "cuda"), default="auto", help="where (auto)"
    )
    bench.add_argument(
        "--scale",
        choices=("auto", *SCALES),
        default="auto",
        help="network and batch sizes: paper on CUDA, small on CPU (auto)",
    )
    _add_rounds(bench)
    bench.add_argument(
        "--precisions",
        help="fast-path precisions, comma-separated "
        f"({', '.join(FAST_PRECISIONS)}; default: tf32,bf16,fp32 on CUDA; on a CPU fp32,bf16 "
        "with native bf16, else fp32)",
    )
    bench.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="override a training setting, e.g. --set hidden=512 (repeatable)",
    )
    bench.add_argument(
        "--full-run",
        action="store_true",
        help="also train the fast path for the whole run length and time it",
    )
    bench.add_argument(
        "--out",
        type=Path,
        help="output path without suffix: OUT.json and OUT.md, not files already there "
        "(default: seqrank-out/bench/bench-<device>)",
    )
    bench.add_argument(
        "--dry-run", action="store_true", help="check the options, print the plan, time nothing"
    )
    bench.set_defaults(handler=run)


def _add_rounds(bench: argparse.ArgumentParser) -> None:
    """How much each interleaved round times."""
    bench.add_argument(
        "--repeats", type=int_between(1, 1000), default=3, help="interleaved rounds, 1 to 1000 (3)"
    )
    bench.add_argument(
        "--updates",
        type=int_between(1, 10**6),
        default=200,
        help="SAC updates timed per round, 1 to 1000000 (200)",
    )
    bench.add_argument(
        "--reward-epochs",
        type=int_between(1, 10**4),
        default=5,
        help="reward epochs per round, 1 to 10000 (5)",
    )
    bench.add_argument(
        "--loop-steps",
        type=int_between(300, 10**7, "a round spans warm-up and feedback"),
        default=2000,
        help="loop steps per round, 300 to 10000000 (2000)",
    )


def run(args: argparse.Namespace, out: Console, err: Console) -> int:
    from seqrank.bench.report import format_markdown
    from seqrank.bench.suite import BenchPlan, run_bench
    from seqrank.training.runtime import resolve_device

    try:
        device = resolve_device(args.device)
        path = args.out or Path("seqrank-out/bench") / f"bench-{device.type}"
        _check_new(path)
        precisions = _precisions(args.precisions, device.type)
        overrides = parse_overrides(args.set)
        plan = BenchPlan.build(args.task, args.scale, device, precisions, overrides, args)
    except ValueError as problem:
        raise UsageError(str(problem)) from None
    if args.dry_run:
        variants = ", ".join(v.name for v in plan.variants)
        err.print(
            f"options valid: {plan.config.task} on {device}, {variants}; "
            f"{plan.total_measurements} measurements, output {path} (dry run)",
            highlight=False,
            soft_wrap=True,
        )
        return 0
    with progress_bar(err) as bar:
        task = bar.add_task("bench", total=plan.total_measurements)
        result = run_bench(
            plan, on_measurement=lambda what: bar.update(task, advance=1, description=what)
        )
    result["command"] = "seqrank " + shlex.join(args.command_line)
    result["host"] = {"machine": platform.machine(), "cpus": os.cpu_count()}
    path.parent.mkdir(parents=True, exist_ok=True)
    markdown = format_markdown(result)
    path.with_suffix(".json").write_text(json.dumps(result, indent=2) + "\n")
    path.with_suffix(".md").write_text(markdown)
    out.print(markdown, markup=False, highlight=False)
    err.print(f"wrote {path.with_suffix('.json')} and {path.with_suffix('.md')}")
    return 0


def _check_new(path: Path) -> None:
    """The two files a bench writes (OUT.json, OUT.md): one already there is refused (a
    ValueError) rather than overwritten."""
    from seqrank.dirs import check_file

    for written in (path.with_suffix(".json"), path.with_suffix(".md")):
        check_file(written, "--out")
        if written.exists():
            raise ValueError(
                f"bench result {written} already exists; choose another --out or remove it"
            )


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """FIELD=VALUE pairs typed like the TrainConfig field they name."""
    types = {f.name: field_type(f) for f in fields(TrainConfig)}
    overrides: dict[str, Any] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name = name.strip().replace("-", "_")
        if not sep or name not in types:
            raise ValueError(
                f"--set {item!r}: expected FIELD=VALUE with FIELD a `seqrank train` setting "
                "(such as hidden, batch, reward_hidden)"
            )
        try:
            overrides[name] = types[name](text)
        except ValueError:
            raise ValueError(f"--set {item!r}: {text!r} is not a {types[name].__name__}") from None
    return overrides


def _precisions(text: str | None, device_type: str) -> list[str]:
    if text is None:
        if device_type == "cuda":
            return ["tf32", "bf16", "fp32"]
        from seqrank.training.cpu_path import native_bf16

        return ["fp32", "bf16"] if native_bf16() else ["fp32"]  # bf16 where it is native
    return split_names(text, FAST_PRECISIONS, "precision")
