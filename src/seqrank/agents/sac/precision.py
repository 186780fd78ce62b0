"""Numeric precision as a context: fp32, TF32 matmuls, or bf16 autocast.

The switches torch offers for TF32 are process-wide, so every use is scoped: the benchmark
runs the strict-fp32 reference and the TF32 fast path interleaved in one process.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch


@contextlib.contextmanager
def matmul_precision(precision: str) -> Iterator[None]:
    """TF32 matmuls and convolutions on CUDA for `tf32` and `bf16`, strict fp32 otherwise."""
    allow = precision in ("tf32", "bf16")
    before = torch.backends.cuda.matmul.allow_tf32, torch.backends.cudnn.allow_tf32
    torch.backends.cuda.matmul.allow_tf32 = allow
    torch.backends.cudnn.allow_tf32 = allow
    try:
        yield
    finally:
        torch.backends.cuda.matmul.allow_tf32, torch.backends.cudnn.allow_tf32 = before


def autocast(precision: str, device: torch.device) -> contextlib.AbstractContextManager[None]:
    """bf16 autocast for forward passes when asked for; a no-op otherwise."""
    if precision == "bf16":
        # no cast cache: casts made while a CUDA graph is captured must not be freed after
        return torch.autocast(device.type, dtype=torch.bfloat16, cache_enabled=False)
    return contextlib.nullcontext()
