from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest

from seqrank.types import Answer


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Tests marked `gpu` are skipped where torch sees no CUDA device."""
    import torch

    if torch.cuda.is_available():
        return
    skip = pytest.mark.skip(reason="gpu: needs a CUDA device")
    for item in items:
        if "gpu" in item.keywords:
            item.add_marker(skip)


def perfect_ask(values: Sequence[float]):  # type: ignore[no-untyped-def]
    """ask(first, second) of a perfect teacher on true `values`; exact ties answer EQUAL."""

    def ask(first: int, second: int) -> Answer:
        if values[first] > values[second]:
            return Answer.FIRST
        if values[second] > values[first]:
            return Answer.SECOND
        return Answer.EQUAL

    return ask


def scripted_ask(script: dict[tuple[int, int], Answer]):  # type: ignore[no-untyped-def]
    """ask() that answers from a fixed script and fails on any question not in it."""

    def ask(first: int, second: int) -> Answer:
        return script[(first, second)]

    return ask


def rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)
