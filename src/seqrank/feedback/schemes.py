"""Comparison schemes: which questions a session asks, given the answers so far.

Every scheme is a function `(pool_size, budget, ask, rng, choose) -> SessionRecord`.
Segments are ids `0 .. pool_size - 1`; `ask(first, second)` returns an `Answer` and never
tells the scheme whether a script or a person answered. `budget` counts questions asked:
skipped answers spend budget too (as in PEBBLE). A drawn segment is never drawn again in
the same session.

Choices this module makes (SPEC section 3 "decide"):
- equal answers add no ordering: sequential still moves on to the challenger (the tie
  closes the monotone chain, because the closure never chains ties); root keeps its root.
- skipped answers add no edge: sequential moves on to the challenger (the chain breaks);
  root keeps its root and the challenger is dropped; ranked drops the segment.
- with a `Recheck` (noise-aware augmentation, `seqrank.feedback.checking`) an answer that
  would imply many pairs is asked again within the budget; the scheme sees it only when
  the repeats agree, and treats it as skipped otherwise;
- the defender is always `first` in a question; showing sides to a person (randomised and
  mapped back) is the labelling page's job, not the scheme's.
- `ranked` inserts each new segment into a ranked list of groups of equally preferred
  segments by binary search against each group's founding member. An EQUAL answer joins the
  group, SKIP drops the segment; when the budget runs out mid-search the segment is not
  placed, but the answers it got still count.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol

import numpy as np

from seqrank.errors import parse_choice
from seqrank.feedback.checking import Recheck, confirmed_answer
from seqrank.feedback.crowd_record import CrowdRecord
from seqrank.types import Answer, AnsweredQuestion, Question

Ask = Callable[[int, int], Answer]


class Chooser(Protocol):
    """Picks the next segment: returns a position in `available` (ids not drawn yet).

    `defender` is the segment the new one will be compared with, or None when there is
    none yet (the first segment of a chain, of a pairwise pair, or a ranked insertion).
    """

    def __call__(
        self, defender: int | None, available: Sequence[int], rng: np.random.Generator
    ) -> int: ...


def uniform_choice(defender: int | None, available: Sequence[int], rng: np.random.Generator) -> int:
    """The default: a uniformly random segment not drawn yet."""
    return int(rng.integers(len(available)))


def in_order_choice(
    defender: int | None, available: Sequence[int], rng: np.random.Generator
) -> int:
    """Draw segments in id order: makes a scheme replay a given ordering exactly."""
    return 0


@dataclass(frozen=True)
class SessionRecord:
    """What one session asked and heard, in order, and which segments it drew."""

    scheme: str
    answers: tuple[AnsweredQuestion, ...]
    segments: tuple[int, ...]
    # (winner, loser) of the answers the fitted model agreed with instead of a repeat
    # (`augment checked`); the closure may take them as confirmed
    vouched: frozenset[tuple[int, int]] = frozenset()
    crowd: CrowdRecord | None = None  # a crowd's session: who answered what

    @property
    def asked(self) -> int:
        return len(self.answers)


class _Session:
    """Bookkeeping shared by the schemes: drawing segments, asking, recording."""

    def __init__(
        self,
        pool_size: int,
        budget: int,
        ask: Ask,
        rng: np.random.Generator,
        choose: Chooser,
        recheck: Recheck | None,
    ):
        opinions = None if recheck is None else recheck.model_returns
        if opinions is not None and len(opinions) != pool_size:
            raise ValueError(
                f"the re-check's model opinions cover {len(opinions)} segments; the pool "
                f"has {pool_size} (opinions belong to the pool they were given for)"
            )
        self.available = list(range(pool_size))
        self.drawn: list[int] = []
        self.answers: list[AnsweredQuestion] = []
        self.vouched: set[tuple[int, int]] = set()
        self.budget, self.recheck = budget, recheck
        self._ask, self._rng, self._choose = ask, rng, choose

    @property
    def budget_left(self) -> int:
        return self.budget - len(self.answers)

    def draw(self, defender: int | None) -> int:
        position = self._choose(defender, self.available, self._rng)
        segment = self.available.pop(position)
        self.drawn.append(segment)
        return segment

    def ask(self, first: int, second: int, first_is_defender: bool) -> Answer:
        """The answer the scheme acts on (a re-checked one when a `Recheck` is set)."""

        def ask_once() -> Answer:
            question = Question(len(self.answers), first, second, first_is_defender)
            answer = self._ask(first, second)
            self.answers.append(AnsweredQuestion(question, answer))
            return answer

        answer = ask_once()
        if self.recheck is None:
            return answer
        repeats, spared = self.recheck.decide(self.answers)
        if spared:
            self.vouched.add((first, second) if answer is Answer.FIRST else (second, first))
        return confirmed_answer(self.answers, repeats, ask_once, lambda: self.budget_left)

    def record(self, scheme: str) -> SessionRecord:
        return SessionRecord(
            scheme, tuple(self.answers), tuple(self.drawn), frozenset(self.vouched)
        )


def pairwise(
    pool_size: int,
    budget: int,
    ask: Ask,
    rng: np.random.Generator,
    choose: Chooser = uniform_choice,
    recheck: Recheck | None = None,
) -> SessionRecord:
    """The baseline: `budget` disjoint pairs of 2 * budget distinct segments."""
    _check_pool("pairwise", pool_size, budget)
    session = _Session(pool_size, budget, ask, rng, choose, recheck)
    while session.budget_left > 0:
        first = session.draw(None)
        second = session.draw(first)
        session.ask(first, second, first_is_defender=False)
    return session.record("pairwise")


def sequential(
    pool_size: int,
    budget: int,
    ask: Ask,
    rng: np.random.Generator,
    choose: Chooser = uniform_choice,
    recheck: Recheck | None = None,
) -> SessionRecord:
    """Sequential pairwise (Algorithm 1): each challenger meets the previous segment."""
    _check_pool("sequential", pool_size, budget)
    session = _Session(pool_size, budget, ask, rng, choose, recheck)
    defender = session.draw(None)
    while session.budget_left > 0:
        challenger = session.draw(defender)
        session.ask(defender, challenger, first_is_defender=True)
        defender = challenger
    return session.record("sequential")


def root(
    pool_size: int,
    budget: int,
    ask: Ask,
    rng: np.random.Generator,
    choose: Chooser = uniform_choice,
    recheck: Recheck | None = None,
) -> SessionRecord:
    """Root pairwise (Algorithm 2): each challenger meets the most preferred so far."""
    _check_pool("root", pool_size, budget)
    session = _Session(pool_size, budget, ask, rng, choose, recheck)
    current_root = session.draw(None)
    while session.budget_left > 0:
        challenger = session.draw(current_root)
        if session.ask(current_root, challenger, first_is_defender=True) is Answer.SECOND:
            current_root = challenger
    return session.record("root")


def ranked(
    pool_size: int,
    budget: int,
    ask: Ask,
    rng: np.random.Generator,
    choose: Chooser = uniform_choice,
    recheck: Recheck | None = None,
) -> SessionRecord:
    """Binary insertion into a ranked list of groups of equally preferred segments."""
    _check_pool("ranked", pool_size, budget)
    session = _Session(pool_size, budget, ask, rng, choose, recheck)
    groups: list[list[int]] = [[session.draw(None)]]  # worst group first
    while session.budget_left > 0 and session.available:
        newcomer = session.draw(None)
        _insert(session, groups, newcomer)
    return session.record("ranked")


def _insert(session: _Session, groups: list[list[int]], newcomer: int) -> None:
    low, high = 0, len(groups)
    while low < high:
        if session.budget_left <= 0:
            return
        middle = (low + high) // 2
        founder = groups[middle][0]
        answer = session.ask(founder, newcomer, first_is_defender=True)
        if answer is Answer.SKIP:
            return
        if answer is Answer.EQUAL:
            groups[middle].append(newcomer)
            return
        if answer is Answer.FIRST:
            high = middle
        else:
            low = middle + 1
    groups.insert(low, [newcomer])


Scheme = Callable[[int, int, Ask, np.random.Generator, Chooser, Recheck | None], SessionRecord]

SCHEMES: dict[str, Scheme] = {
    "pairwise": pairwise,
    "sequential": sequential,
    "root": root,
    "ranked": ranked,
}


def get_scheme(name: str) -> Scheme:
    """The scheme called `name`; a ValueError names the accepted schemes."""
    try:
        return SCHEMES[name]
    except KeyError:
        raise ValueError(f"unknown scheme {name!r}; accepted: {', '.join(SCHEMES)}") from None


def segments_needed(scheme: str, budget: int, chains: int = 1) -> int:
    """How many distinct segments a session of `budget` questions may draw, asked as
    `chains` chains of its scheme side by side (a crowd's session, one chain a person).
    Several chains keep `handover_reserve` segments more."""
    if not scheme_has_defender(scheme):
        return 2 * budget
    # a chain's first segment: one at least, so an empty session still draws a defender
    first_segments = max(1, min(chains, budget))
    return budget + first_segments + handover_reserve(scheme, budget, chains)


def handover_reserve(scheme: str, budget: int, chains: int) -> int:
    """Segments a crowd's session keeps aside so that a chain handed over to another
    person (who starts it afresh from a new first segment) has one more: one a chain."""
    used = min(chains, budget)
    return used if used > 1 and scheme_has_defender(scheme) else 0


def _check_pool(scheme: str, pool_size: int, budget: int) -> None:
    if budget < 1:
        raise ValueError(f"{scheme}: the question budget must be at least 1, got {budget}")
    needed = segments_needed(scheme, budget)
    if scheme == "ranked":
        needed = 2  # ranked stops early when the pool runs out
    if pool_size < needed:
        raise ValueError(
            f"{scheme}: {budget} questions need at least {needed} distinct segments, "
            f"but the pool has {pool_size}"
        )


class SchemeName(StrEnum):
    """The comparison schemes by name; `seqrank.SCHEMES` is their values in this order.

    Examples:
        >>> import seqrank
        >>> seqrank.SCHEMES
        ('pairwise', 'sequential', 'root', 'ranked')
        >>> [s.has_defender for s in SchemeName]  # a kept segment against each new one
        [False, True, True, True]
    """

    PAIRWISE = "pairwise"
    SEQUENTIAL = "sequential"
    ROOT = "root"
    RANKED = "ranked"

    @property
    def has_defender(self) -> bool:
        """True when questions pit a new challenger against a kept defender."""
        return self is not SchemeName.PAIRWISE


def scheme_has_defender(name: str) -> bool:
    """True for schemes whose questions pit a challenger against a kept defender."""
    return parse_choice(SchemeName, name, "scheme").has_defender
