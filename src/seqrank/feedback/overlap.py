"""Which of a crowd's answers are asked again of a second person: the adaptive overlap
(issue 49).

A flag needs about 40 answers per person checked against somebody else's before it can
tell a member who errs 3 times in 10 from one who errs once in 10 (`peer_reliability`):
at a fixed overlap of 0.1 that is 400 answers each. So every answer of a person whose
answers shared with others number fewer than `until` is asked again, of the other person
with the fewest shared answers (who needs the evidence most); after that, a share
`overlap` of the answers, of anyone else, as before. Overlaps cost person-time, never
questions: a second opinion is not a question of the budget.

`needs_second_opinion` and `checker` are what a page that asks people one answer at a time
calls; `adaptive_picks` is the simulated crowd's session at once.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from seqrank.feedback.schemes import SessionRecord
from seqrank.types import Answer


def needs_second_opinion(
    shared: Mapping[str, int], owner: str, until: int, overlap: float, draw: float
) -> bool:
    """Whether `owner`'s answer is asked again: always while their shared answers number
    fewer than `until`, else when `draw` (uniform in [0, 1)) falls below `overlap`."""
    return shared.get(owner, 0) < until or draw < overlap


def checker(
    shared: Mapping[str, int], owner: str, people: Sequence[str], rng: np.random.Generator
) -> str:
    """Who answers it again: among the others, one of those with the fewest shared answers."""
    others = [name for name in people if name != owner]
    fewest = min(shared.get(name, 0) for name in others)
    neediest = [name for name in others if shared.get(name, 0) == fewest]
    return neediest[int(rng.integers(len(neediest)))]


def adaptive_picks(
    record: SessionRecord,
    people: Sequence[str],
    shared: dict[str, int],
    until: int,
    overlap: float,
    rng: np.random.Generator,
) -> list[tuple[int, str]]:
    """(answer index, who answers it again) for the session's answers, in order; `shared`
    (each person's answers shared with others so far) counts the picks as it goes."""
    if len(people) < 2 or record.crowd is None:
        return []
    picks = []
    for k, asked in enumerate(record.answers):
        owner, draw = record.crowd.answered_by[k], rng.random()
        if asked.answer is Answer.SKIP or not needs_second_opinion(
            shared, owner, until, overlap, draw
        ):
            continue
        second = checker(shared, owner, people, rng)
        shared[owner], shared[second] = shared.get(owner, 0) + 1, shared.get(second, 0) + 1
        picks.append((k, second))
    return picks
