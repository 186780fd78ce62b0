"""Is the flat update still needed? It exists because eager autograd is slower on a CPU,
and goes when `torch.compile` of the autograd update is as fast (its deletion condition,
`seqrank/agents/sac/flat_update.py`). This times, from the same weights, batch and noise:

- the flat update (what `--path fast` runs on a CPU),
- the autograd update the fast path runs on CUDA (stacked critics, fused Adam), eager,
- the same autograd update compiled (`torch.compile` of `SAC._step`: both losses, their
  backward passes and the Adam steps; the precision context stays around it, as in a run),

at the small preset's walker sizes unless given others, and says whether the condition
holds. The compiled update's losses are checked against the eager one's after the same
updates, so a compile that computes something else is not timed as a win.

    OMP_NUM_THREADS=1 .venv/bin/python scripts/compile_probe.py [--precision fp32|bf16]
    OMP_NUM_THREADS=1 .venv/bin/python scripts/compile_probe.py --hidden 32 --batch 32 --updates 5
"""

from __future__ import annotations

import argparse
import math
import time

import torch

from seqrank.agents.sac import SAC, Execution, SACSettings
from seqrank.buffer import Batch

OBS, ACT = 24, 6  # walker_walk
CPU = torch.device("cpu")
WARMUP = 3  # the compiled update's first calls compile (and recompile once Adam has state)


def settings(hidden: int) -> SACSettings:
    return SACSettings(
        hidden=hidden,
        layers=2,
        actor_lr=5e-4,
        critic_lr=5e-4,
        alpha_lr=1e-4,
        init_temperature=0.1,
        discount=0.99,
        tau=0.005,
        target_update_every=2,
    )


def batch_of(rows: int) -> Batch:
    generator = torch.Generator().manual_seed(1)
    return Batch(
        torch.randn(rows, OBS, generator=generator),
        torch.rand(rows, ACT, generator=generator) * 2 - 1,
        torch.randn(rows, 1, generator=generator),
        torch.randn(rows, OBS, generator=generator),
        torch.ones(rows, 1),
    )


def agents(hidden: int, precision: str) -> dict[str, SAC]:
    """The three updates from one start (weights copied from a reference agent)."""
    torch.manual_seed(0)
    start = SAC(OBS, ACT, settings(hidden), CPU)
    autograd = Execution(stacked_critics=True, fused_adam=True, precision=precision)
    made = {
        "flat": SAC(OBS, ACT, settings(hidden), CPU, Execution.fast(CPU, precision)),
        "autograd, eager": SAC(OBS, ACT, settings(hidden), CPU, autograd),
        "autograd, compiled": SAC(OBS, ACT, settings(hidden), CPU, autograd),
    }
    for agent in made.values():
        agent.load_state_dict(start.state_dict())
    compiled = made["autograd, compiled"]
    compiled._step = torch.compile(compiled._step)  # type: ignore[method-assign]
    return made


def time_updates(agent: SAC, batch: Batch, updates: int) -> tuple[float, float]:
    """(seconds of the warm-up updates, microseconds per update after them)."""
    generator = torch.Generator().manual_seed(2)
    started = time.perf_counter()
    for _ in range(WARMUP):
        agent.update(batch, generator)
    warmup = time.perf_counter() - started
    started = time.perf_counter()
    for _ in range(updates):
        agent.update(batch, generator)
    return warmup, (time.perf_counter() - started) / updates * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--precision", choices=("fp32", "bf16"), default="fp32")
    parser.add_argument("--hidden", type=int, default=256)
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--updates", type=int, default=50)
    args = parser.parse_args()
    batch = batch_of(args.batch)
    timed = {}
    for name, agent in agents(args.hidden, args.precision).items():
        warmup, per_update = time_updates(agent, batch, args.updates)
        timed[name] = (per_update, agent.last_metrics["critic_loss"])
        print(f"{name:20} {per_update:9.0f} µs an update   (first {WARMUP}: {warmup:.1f} s)")
    eager_loss, compiled_loss = timed["autograd, eager"][1], timed["autograd, compiled"][1]
    same = math.isclose(compiled_loss, eager_loss, rel_tol=1e-2)
    print(f"compiled critic loss {compiled_loss:.6g}, eager {eager_loss:.6g}: ", end="")
    print("the same update" if same else "NOT the same update: its time means nothing")
    faster = timed["autograd, compiled"][0] <= timed["flat"][0]
    verdict = "holds: the flat update can go" if same and faster else "does not hold"
    sizes = f"{args.precision}, hidden {args.hidden}, batch {args.batch}"
    print(f"{sizes}: the deletion condition {verdict}")


if __name__ == "__main__":
    main()
