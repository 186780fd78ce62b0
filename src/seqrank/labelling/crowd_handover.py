"""A chain handed over: what its continuation asks, and from which segments.

A question left unanswered too long cuts its chain; what the chain had left to ask becomes
a new chain from the segments its answers did not use and one of the session's reserve
(so that the continuation starts afresh from a new first segment and never mixes people).
"""

from __future__ import annotations

from seqrank.feedback.schemes import segments_needed
from seqrank.labelling.crowd_db import ChainRow


def continuation(
    scheme: str,
    cut: ChainRow,
    used: set[int],
    answered: int,
    stored: list[ChainRow],
    pool_size: int,
) -> ChainRow | None:
    """The chain that asks what `cut` had left after `answered` answers that used the pool
    ids `used`, numbered after the `stored` chains; None when nothing can be asked."""
    pool = [s for s in cut.pool if s not in used]
    pool += _reserve_segment(stored, pool_size)
    left = cut.budget - answered
    budget = max(0, min(left, _fits(scheme, len(pool))))
    if budget == 0:
        return None
    number = max(c.chain for c in stored) + 1
    return ChainRow(cut.run, cut.session, number, cut.chain, budget, tuple(pool), None)


def _reserve_segment(stored: list[ChainRow], pool_size: int) -> list[int]:
    """One segment of the session's reserve that no continuation has taken yet."""
    first = [c for c in stored if c.parent is None]
    used = {s for c in first for s in c.pool}
    reserve = [s for s in range(pool_size) if s not in used]
    taken = {s for c in stored if c.parent is not None for s in c.pool}
    free = [s for s in reserve if s not in taken]
    return free[:1]


def _fits(scheme: str, segments: int) -> int:
    """The most questions of `scheme` that `segments` distinct segments allow."""
    budget = 0
    while segments_needed(scheme, budget + 1) <= segments:
        budget += 1
    return budget
