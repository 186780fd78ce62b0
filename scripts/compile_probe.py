"""Does torch.compile speed up the fast SAC update here? Times 50 eager updates, compiles
the update (`SAC.update_with_noise`, run the fast way), then times 50 compiled ones
(walker sizes of the small preset), in the precision given (fp32 or bf16).

    OMP_NUM_THREADS=1 .venv/bin/python scripts/compile_probe.py [fp32|bf16]
"""

from __future__ import annotations

import sys
import time

import torch

from seqrank.agents.sac import SAC, Execution, SACSettings
from seqrank.buffer import Batch


def main() -> None:
    settings = SACSettings(256, 2, 5e-4, 5e-4, 1e-4, 0.1, 0.99, 0.005, 2)
    torch.manual_seed(0)
    cpu = torch.device("cpu")
    precision = sys.argv[1] if len(sys.argv) > 1 else "fp32"
    agent = SAC(24, 6, settings, cpu, Execution.fast(cpu, precision))
    generator = torch.Generator().manual_seed(1)
    rows = 256
    batch = Batch(
        torch.randn(rows, 24, generator=generator),
        torch.rand(rows, 6, generator=generator) * 2 - 1,
        torch.randn(rows, 1, generator=generator),
        torch.randn(rows, 24, generator=generator),
        torch.ones(rows, 1),
    )

    def per_update() -> float:
        started = time.perf_counter()
        for _ in range(50):
            agent.update(batch, generator)
        return (time.perf_counter() - started) / 50 * 1e6

    agent.update(batch, generator)
    eager = per_update()
    agent.update_with_noise = torch.compile(agent.update_with_noise)  # type: ignore[method-assign]
    started = time.perf_counter()
    agent.update(batch, generator)
    compile_seconds = time.perf_counter() - started
    compiled = per_update()
    print(f"{precision}: eager {eager:.0f} µs, compiled {compiled:.0f} µs, ", end="")
    print(f"compile {compile_seconds:.1f} s")


if __name__ == "__main__":
    main()
