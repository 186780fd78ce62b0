"""Load a finished run and its policy, and watch the policy act for one episode.

python examples/load_a_run.py seqrank-out/examples/judge
"""

from __future__ import annotations

import sys

import torch

import seqrank


def main() -> None:
    run = seqrank.load_run(sys.argv[1] if len(sys.argv) > 1 else "seqrank-out/examples/judge")
    print(f"{run.config.task}, {run.config.scheme} scheme, {run.config.steps} steps")
    print("evaluations (step, return):", [(s, round(r, 1)) for s, r in run.evaluations()])
    policy, env = run.policy(), run.environment(seed=123)
    obs, _ = env.reset(seed=123)
    total, done, generator = 0.0, False, torch.Generator().manual_seed(0)
    while not done:
        obs, reward, terminated, truncated, _ = env.step(policy.act(obs, True, generator))
        total, done = total + reward, terminated or truncated
    print(f"one more episode with the saved policy: return {total:.1f}")


if __name__ == "__main__":
    main()
