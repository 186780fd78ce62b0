"""Scripted answers for scheme and closure tests."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from seqrank.types import Answer


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
