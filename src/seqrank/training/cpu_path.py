"""What `--path auto` picks on a CPU: the fast path (the flat update) in bf16 where that
is measured to be faster on this machine and to learn the same; else the flat update in
fp32 where that is measured faster; the reference path otherwise.

bf16 matmuls are fast only where the processor does bf16 natively (AVX-512 BF16, AMX): on
an AVX2-only processor they were measured 13x slower, so nothing is chosen by guess. The
flat update in fp32 computes what the reference update computes, in the same precision
(held to autograd in `tests/agents/test_flat_update.py`); on an AVX2 processor it was
measured 1.14x faster per update and 1.26x per loop step (issue 45). The choice takes
three facts:

- the processor's flags name native bf16 (`/proc/cpuinfo`; elsewhere: no) and torch's
  kernels run at that level (`torch.backends.cpu.get_cpu_capability()` AVX512: with
  `ATEN_CPU_CAPABILITY=avx2` they do not, and bf16 is emulated);
- the run's networks are at least the sizes whose learning was checked side by side
  (`results/speed/walker-flat-bf16-cpu.toml`: 256 x 2, batch 256; smaller ones stay
  reference);
- a measurement of the updates at the run's own shapes, on this machine, with the torch
  threads a fast run trains with (`training_threads`), finds the flat update in bf16 at
  least `MIN_SPEEDUP` times faster than the reference (or, failing that, in fp32 at least
  `MIN_FP32_SPEEDUP` times). It takes about a second a precision, and is kept in
  `~/.cache/seqrank/cpu-paths.json` (`SEQRANK_CACHE` moves it), so the choice is made once
  per machine and shape, and two runs on one machine take the same path.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import tempfile
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import torch

from seqrank.config import TrainConfig

if TYPE_CHECKING:
    from seqrank.agents.sac import SACSettings

NATIVE_BF16_FLAGS = ("avx512_bf16", "amx_bf16")
MIN_SPEEDUP = 1.25  # bf16: a lower precision pays for itself only with a clear gain
MIN_FP32_SPEEDUP = 1.05  # fp32: the same computation, taken when measurably faster
CHECKED_HIDDEN, CHECKED_BATCH = 256, 256  # the learning check's sizes
ROUNDS, UPDATES, WARMUP = 3, 20, 5
MEASURED = "flat update"  # what was timed: a cached measurement of another update is redone
NATIVE_BF16_CAPABILITY = "AVX512"  # torch's kernel level that runs bf16 natively


@dataclass(frozen=True)
class UpdateShape:
    """The sizes that decide what a SAC update costs."""

    obs_dim: int
    act_dim: int
    hidden: int
    layers: int
    batch: int

    @property
    def checked(self) -> bool:
        return self.hidden >= CHECKED_HIDDEN and self.batch >= CHECKED_BATCH


def cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    line = next((line for line in text.splitlines() if line.startswith("flags")), "")
    return set(line.partition(":")[2].split())


def training_threads(fast: bool) -> int:
    """Torch's intra-op threads for a CPU run: on the fast path one core fewer than the
    machine has (at least one, never more than torch's own setting), because its evaluation
    runs in a process of its own and its feedback sessions in a thread: with every core in
    torch's pool those stall each update (the main job on a 2-core machine took 13.2 min
    with two threads, 10.2 with one: `results/main-job-cpu.md`). The reference path, which
    evaluates inline, keeps torch's setting."""
    if not fast:
        return torch.get_num_threads()
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, min(torch.get_num_threads(), (cores or 1) - 1))


@contextlib.contextmanager
def torch_threads(count: int) -> Iterator[None]:
    """Torch's intra-op thread count set to `count` for a while, then put back."""
    before = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def native_bf16() -> bool:
    return bool(cpu_flags() & set(NATIVE_BF16_FLAGS)) and torch_capability() == (
        NATIVE_BF16_CAPABILITY
    )


def torch_capability() -> str:
    """The vector level torch's CPU kernels run at (AVX2, AVX512, ...)."""
    return str(torch.backends.cpu.get_cpu_capability())


def auto_cpu_precision(shape: UpdateShape) -> str | None:
    """The precision `--path auto` trains this shape's flat update in on this CPU (bf16
    or fp32), or None: the reference path."""
    if not shape.checked:
        return None
    if native_bf16() and measured_speedup(shape, "bf16") >= MIN_SPEEDUP:
        return "bf16"
    return "fp32" if measured_speedup(shape, "fp32") >= MIN_FP32_SPEEDUP else None


def measured_speedup(shape: UpdateShape, precision: str = "bf16") -> float:
    """How many times faster the flat update in `precision` is than the reference one
    (cached)."""
    cache = _cache_file()
    threads = training_threads(fast=True)
    key = (
        f"{_machine()}|torch {torch.__version__}|threads {threads}|{asdict(shape)}|"
        f"{MEASURED} {precision}"
    )
    known = _read(cache)
    if key not in known:
        with torch_threads(threads):
            known[key] = _measure(shape, precision)
        _write(cache, {**_read(cache), key: known[key]})
    return float(known[key])


def timed_settings(shape: UpdateShape) -> SACSettings:
    """The SAC whose updates are timed: a default run's (`TrainConfig()`) at the shape's
    sizes. Of the other settings only `target_update_every` changes an update's cost (the
    learning rates, temperature and discount change its numbers, not its operations)."""
    from seqrank.agents.sac import SACSettings

    sized = replace(TrainConfig(), hidden=shape.hidden, layers=shape.layers)
    return SACSettings.from_config(sized)


def _measure(shape: UpdateShape, precision: str) -> float:
    """Median of interleaved rounds; the global random state is left as it was."""
    from seqrank.agents.sac import SAC, Execution
    from seqrank.buffer import Batch

    with torch.random.fork_rng():
        settings = timed_settings(shape)
        cpu = torch.device("cpu")
        agents = [SAC(shape.obs_dim, shape.act_dim, settings, cpu)]
        flat = Execution.fast(cpu, precision)  # what the run would take: the flat update
        agents.append(SAC(shape.obs_dim, shape.act_dim, settings, cpu, flat))
        generator = torch.Generator().manual_seed(0)
        rows, obs, act = shape.batch, shape.obs_dim, shape.act_dim
        batch = Batch(
            torch.randn(rows, obs), torch.rand(rows, act) * 2 - 1, torch.randn(rows, 1),
            torch.randn(rows, obs), torch.ones(rows, 1),
        )  # fmt: skip
        times: list[list[float]] = [[], []]
        for _ in range(ROUNDS):
            for agent, kept in zip(agents, times, strict=True):
                for _ in range(WARMUP):
                    agent.update(batch, generator)
                started = time.perf_counter()
                for _ in range(UPDATES):
                    agent.update(batch, generator)
                kept.append(time.perf_counter() - started)
    reference, fast = (sorted(t)[len(t) // 2] for t in times)
    return reference / fast


VECTOR_FLAGS = ("avx2", "avx512f", "avx512_bf16", "amx_bf16")  # what sets a run's speed


def processor() -> dict[str, object]:
    """The CPU a run ran on, as its meta.json records it: speeds and rounding differ
    between machines of one kind (native bf16 or avx2 only)."""
    return {
        "model": _machine(),
        "flags": sorted(cpu_flags() & set(VECTOR_FLAGS)),
        "torch_capability": torch_capability(),
    }


def _machine() -> str:
    model = next(
        (
            line.partition(":")[2].strip()
            for line in _cpuinfo_lines()
            if line.startswith("model name")
        ),
        platform.processor() or platform.machine(),
    )
    return model


def _cpuinfo_lines() -> list[str]:
    with contextlib.suppress(OSError):
        return Path("/proc/cpuinfo").read_text().splitlines()
    return []


def _cache_file() -> Path:
    root = os.environ.get("SEQRANK_CACHE") or Path.home() / ".cache" / "seqrank"
    return Path(root) / "cpu-paths.json"


def _read(path: Path) -> dict[str, float]:
    try:
        value = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return value if isinstance(value, dict) else {}


def _write(path: Path, value: dict[str, float]) -> None:
    """Atomically; a cache that cannot be written is measured again next time."""
    with contextlib.suppress(OSError):
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False) as handle:
            json.dump(value, handle, indent=1)
        os.replace(handle.name, path)
