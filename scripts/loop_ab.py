"""Two source trees' training loops timed side by side: interleaved rounds of `seqrank
bench`'s loop measurement (the fast path, one torch thread) with each tree on PYTHONPATH,
printing steps per second, the collection step's microseconds (action, simulator, store
with the learned reward) and the SAC update's, then the medians.

    git worktree add /tmp/before <commit>
    python scripts/loop_ab.py --before /tmp/before/src --after src --rounds 5

The bench module of `--after` times both trees (copy it over `--before`'s when that one
predates the collection-step measurement).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

MEASURE = """
import json, torch
torch.set_num_threads(1)
import seqrank
from seqrank.api import make_config
from seqrank.bench.measure import loop_rates, update_microseconds
assert seqrank.__file__.startswith({tree!r}), seqrank.__file__
config, cpu = make_config({task!r}, "small"), torch.device("cpu")
loop = loop_rates(config, cpu, True, {precision!r}, {steps})
update = update_microseconds(config, cpu, True, {precision!r}, 200)
print(json.dumps({{"steps_per_s": loop["steps_per_s"], "collect_us": loop["collect_us"],
                  "update_us": update["us"]}}))
"""


def measure(tree: str, args: argparse.Namespace) -> dict[str, float]:
    code = MEASURE.format(tree=os.path.abspath(tree), task=args.task, steps=args.steps,
                          precision=args.precision)  # fmt: skip
    environment = {**os.environ, "PYTHONPATH": os.path.abspath(tree)}
    done = subprocess.run(
        [sys.executable, "-c", code], env=environment, capture_output=True, text=True, check=True
    )
    row: dict[str, float] = json.loads(done.stdout.strip().splitlines()[-1])
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", required=True, help="the first tree's src folder")
    parser.add_argument("--after", required=True, help="the second tree's src folder")
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds (5)")
    parser.add_argument("--steps", type=int, default=1500, help="loop steps a round (1500)")
    parser.add_argument("--task", default="walker_walk", help="(walker_walk)")
    parser.add_argument("--precision", default="fp32", help="the flat update's (fp32)")
    args = parser.parse_args()
    rows: dict[str, list[dict[str, float]]] = {"before": [], "after": []}
    for round_ in range(args.rounds):
        for name in rows:
            rows[name].append(measure(getattr(args, name), args))
            print(f"round {round_ + 1} {name}: {json.dumps(rows[name][-1])}", flush=True)
    for name, measured in rows.items():
        medians = {key: statistics.median(r[key] for r in measured) for key in measured[0]}
        print(f"median {name}: " + ", ".join(f"{k} {v:.1f}" for k, v in medians.items()))


if __name__ == "__main__":
    main()
