"""Which of a crowd's answers are asked again of a second person: the adaptive overlap
(issue 49).

A flag needs about 40 answers per person checked against somebody else's before it can
tell a member who errs 3 times in 10 from one who errs once in 10 (`peer_reliability`):
at a fixed overlap of 0.1 that is 400 answers each. So every answer of a person whose
answers shared with others number fewer than `until` is asked again of `CHECKERS` others
(those with the fewest shared answers, who need the evidence most): three opinions on a
pair have a majority, where two that disagree leave the estimator unsure whom to blame
(with two, a never-wrong member was estimated as low as 0.86 beside a member wrong 3 times
in 10, in the pilot of results/crowd/). After that, a share `overlap` of the answers is
asked again of one other person. Overlaps cost person-time, never questions: a second
opinion is not a question of the budget.

Under `crowd_weighting` reask, an answer of a member flagged before the session gets no
such opinion: it is asked again of as many members not flagged as the overlap would ask
about it, at least one (`reasked`, `reasks_wanted`), whose answers train in its place; the
simulated crowd and the page follow this one rule.

`opinions_wanted` and `checkers` are what a page that asks people one answer at a time
calls; `adaptive_picks` is the simulated crowd's session at once.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence

import numpy as np

from seqrank.feedback.schemes import SessionRecord
from seqrank.types import Answer

CHECKERS = 2  # others asked while the owner's evidence is short: three opinions a pair
EVIDENCE_UNTIL = 50  # a run's default `until` (results/crowd/README.md, issue 49)
OVERLAP = 0.1  # a run's default share of answers asked again of one other after that


def reasked(author: str, distrusted: Collection[str], people: Sequence[str]) -> bool:
    """Whether `author`'s answer is asked again of somebody not flagged, in place of the
    overlap's opinions: its author is `distrusted` (flagged before the session, under
    reask) and somebody among `people` is not."""
    return author in distrusted and any(name not in distrusted for name in people)


def opinions_wanted(shared: int, until: int, overlap: float, draw: float) -> int:
    """How many others are asked about an answer whose author has `shared` answers shared
    with others (before the cap of who there is to ask): `CHECKERS` while fewer than
    `until`, else one when `draw` (uniform in [0, 1)) falls below `overlap`, else none."""
    if shared < until:
        return CHECKERS
    return 1 if draw < overlap else 0


def reasks_wanted(shared: int, until: int, overlap: float, draw: float) -> int:
    """How many members not flagged are asked a flagged member's answer under reask: as
    many as the overlap would ask about it, at least one."""
    return max(1, opinions_wanted(shared, until, overlap, draw))


def checkers(
    shared: Mapping[str, int],
    owner: str,
    people: Sequence[str],
    rng: np.random.Generator,
    count: int = 1,
) -> list[str]:
    """Who answers it again: `count` of the others (all, if fewer), those with the fewest
    shared answers first, ties in random order."""
    others = [name for name in people if name != owner]
    ties = rng.permutation(len(others))
    ranked = sorted(range(len(others)), key=lambda k: (shared.get(others[k], 0), ties[k]))
    return [others[k] for k in ranked[:count]]


def adaptive_picks(
    record: SessionRecord,
    people: Sequence[str],
    shared: dict[str, int],
    until: int,
    overlap: float,
    rng: np.random.Generator,
    exempt: Collection[str] = (),
) -> list[tuple[int, str]]:
    """(answer index, who answers it again) for the session's answers, in order (an
    answer of a member short of evidence twice, by two others), none of an `exempt`
    member's (their answers are re-asked instead); `shared` (each person's answers
    shared with others so far) counts the picks as it goes."""
    if len(people) < 2 or record.crowd is None:
        return []
    picks = []
    for k, asked in enumerate(record.answers):
        owner, draw = record.crowd.answered_by[k], rng.random()
        wanted = opinions_wanted(shared.get(owner, 0), until, overlap, draw)
        if asked.answer is Answer.SKIP or owner in exempt or not wanted:
            continue
        others = checkers(shared, owner, people, rng, wanted)
        for name in [owner, *others]:
            shared[name] = shared.get(name, 0) + 1
        picks += [(k, name) for name in others]
    return picks
