"""Capture any update in a CUDA graph and replay it: the launch cost of its few hundred
kernels is paid once instead of at every step.

CUDA graphs need their inputs at fixed addresses and a warm-up on a side stream before
capture; the warm-up changes the weights and optimiser state, so it is rolled back.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import torch

WARMUP_RUNS = 3  # eager runs on a side stream before capture, as CUDA graphs require


class GraphedCall:
    """`fn` captured once and replayed. `touched` lists every tensor `fn` changes (weights,
    optimiser state); with `warmup`, they are restored after the warm-up runs."""

    def __init__(
        self,
        fn: Callable[[], None],
        touched: Callable[[], list[torch.Tensor]],
        warmup: bool = True,
    ):
        self.fn, self.touched, self.warmup = fn, touched, warmup
        self.graph: torch.cuda.CUDAGraph | None = None
        self.capture_seconds = 0.0

    def __call__(self) -> None:
        if self.graph is None:
            self.capture()
        assert self.graph is not None
        self.graph.replay()

    def capture(self) -> None:
        started = time.perf_counter()
        if self.warmup:
            saved = [(t, t.detach().clone()) for t in self.touched()]
            side = torch.cuda.Stream()
            side.wait_stream(torch.cuda.current_stream())
            with torch.cuda.stream(side):
                for _ in range(WARMUP_RUNS):
                    self.fn()
            torch.cuda.current_stream().wait_stream(side)
            with torch.no_grad():
                for tensor, copy in saved:
                    tensor.copy_(copy)
        graph = torch.cuda.CUDAGraph()
        with torch.cuda.graph(graph):
            self.fn()
        torch.cuda.synchronize()
        self.graph = graph
        self.capture_seconds += time.perf_counter() - started
