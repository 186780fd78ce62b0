"""IQL's update timed before and after a change, side by side in one process: the agent of
`--before` (a git commit's `agents/iql.py`, loaded from git) and today's, at Meta-World's
sizes (observations 39, actions 4), two hidden layers of 256, batch 256, one torch thread.
Rounds interleave the variants (before, after, before, after, ...) so that a machine whose
load changes treats both alike; each round times `--updates` updates of each, and the
medians over rounds are printed (and the median of each round's ratio: the load a round
ran under cancels in it), with the CPU (model, avx2 / avx512f / avx512_bf16) and
torch's version.

Before timing, both agents start from the same seed and take the same batches for
`--check` updates; the largest relative difference of any logged loss or statistic between
them is printed: a change that only restructures the update keeps it at rounding (~1e-6).

    python scripts/iql_bench.py --before 83db08d --rounds 60 --updates 10
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import torch

from seqrank.buffer import Batch

ROOT = Path(__file__).resolve().parent.parent
OBS, ACT, ROWS = 39, 4, 100_000  # Meta-World's sizes; a dataset of LiRE's per-seed size
FLAGS = ("avx2", "avx512f", "avx512_bf16")


def module_at(commit: str) -> ModuleType:
    """`agents/iql.py` as it was at `commit`, as a module of its own."""
    source = subprocess.run(
        ["git", "show", f"{commit}:src/seqrank/agents/iql.py"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    spec = importlib.util.spec_from_loader(f"iql_at_{commit}", loader=None)
    assert spec is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up by name
    exec(compile(source, f"{commit}:agents/iql.py", "exec"), module.__dict__)
    return module


def today() -> ModuleType:
    from seqrank.agents import iql

    return iql


def make_agent(module: ModuleType, seed: int) -> Any:
    torch.manual_seed(seed)
    return module.IQL(OBS, ACT, module.IQLSettings(), torch.device("cpu"))


def batches(count: int, seed: int) -> list[Batch]:
    g = torch.Generator().manual_seed(seed)
    obs, next_obs = torch.randn(ROWS, OBS, generator=g), torch.randn(ROWS, OBS, generator=g)
    action = torch.rand(ROWS, ACT, generator=g) * 2 - 1
    reward, not_done = torch.rand(ROWS, 1, generator=g), torch.ones(ROWS, 1)
    out = []
    for _ in range(count):
        i = torch.randint(ROWS, (256,), generator=g)
        out.append(Batch(obs[i], action[i], reward[i], next_obs[i], not_done[i]))
    return out


def largest_difference(before: ModuleType, after: ModuleType, updates: int) -> float:
    """The largest relative difference of a logged number over `updates` updates of two
    agents from the same seed on the same batches."""
    a, b = make_agent(before, 0), make_agent(after, 0)
    worst = 0.0
    for batch in batches(updates, 1):
        a.update(batch)
        b.update(batch)
        for key, x in a.last_metrics.items():
            y = b.last_metrics[key]
            worst = max(worst, abs(x - y) / max(abs(x), abs(y), 1e-12))
    return worst


def time_updates(agent: Any, work: list[Batch]) -> float:
    """Milliseconds per update over `work`."""
    started = time.perf_counter()
    for batch in work:
        agent.update(batch)
    return (time.perf_counter() - started) / len(work) * 1e3


def cpu() -> dict[str, Any]:
    model, flags = platform.processor() or "?", set()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
            elif line.startswith("flags"):
                flags = set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return {"model": model, **{flag: flag in flags for flag in FLAGS}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", required=True, help="a commit: its agents/iql.py is before")
    parser.add_argument("--rounds", type=int, default=9, help="interleaved rounds (9)")
    parser.add_argument("--updates", type=int, default=100, help="updates a round, each (100)")
    parser.add_argument("--check", type=int, default=50, help="updates compared (50)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    variants = {"before": module_at(args.before), "after": today()}
    difference = largest_difference(variants["before"], variants["after"], args.check)
    agents = {name: make_agent(module, 0) for name, module in variants.items()}
    work = batches(args.updates, 2)
    for agent in agents.values():  # warm-up: allocations, the first Adam step
        time_updates(agent, work[:10])
    times: dict[str, list[float]] = {name: [] for name in agents}
    for round_ in range(args.rounds):
        for name, agent in agents.items():
            times[name].append(time_updates(agent, work))
        print(f"round {round_ + 1}: " + ", ".join(f"{n} {t[-1]:.2f} ms" for n, t in times.items()))
    medians = {name: statistics.median(t) for name, t in times.items()}
    result = {
        "cpu": cpu(),
        "torch": torch.__version__,
        "threads": torch.get_num_threads(),
        "before": args.before,
        "ms_per_update": {name: round(m, 3) for name, m in medians.items()},
        "speedup": round(medians["before"] / medians["after"], 3),
        # each round's before / after, paired: the load a round ran under cancels
        "paired_speedup_median": round(
            statistics.median(b / a for b, a in zip(times["before"], times["after"], strict=True)),
            3,
        ),
        "largest_relative_difference": difference,
        "rounds": args.rounds,
        "updates_per_round": args.updates,
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
