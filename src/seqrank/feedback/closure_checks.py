"""The closure as evidence of reliability (issue 49): a second opinion asked on a pair the
closure inferred from someone's chain, instead of a pair they were asked.

Our schemes infer more pairs than they ask (a sequential chain of n answers implies up to
n(n+1)/2 orders), so one second opinion on an inferred pair checks several answers at once:
a chain that implies "a before c" through "a before b" and "b before c" is wrong about it
only if one of those is. The implied order counts as an answer of the chain's owner
(`SecondOpinion.implied`): their answers imply it, so they are answerable for it. This
attribution is harsher than a pair they were asked (an implied order is wrong more often
than any one answer on its path), which a flag threshold set on asked pairs must allow for.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from seqrank.feedback.closure import augment
from seqrank.feedback.schemes import SessionRecord
from seqrank.types import Answer, AnsweredQuestion, LabelledPair


def chain_inferences(record: SessionRecord) -> dict[str, list[LabelledPair]]:
    """Each owner's strict inferred pairs, from the closure of their own answers."""
    assert record.crowd is not None
    answers: dict[str, list[AnsweredQuestion]] = {}
    for asked, owner in zip(record.answers, record.crowd.answered_by, strict=True):
        answers.setdefault(owner, []).append(asked)
    return {
        owner: [p for p in augment(own).pairs if p.inferred and p.label != 0.5]
        for owner, own in answers.items()
    }


def pair_to_check(
    inferred: Sequence[LabelledPair], asked: AnsweredQuestion, rng: np.random.Generator
) -> tuple[int, int, Answer] | None:
    """An inferred pair that shares a segment with `asked` (drawn at random), and the
    answer the chain implies on it; None when the closure inferred none."""
    touching = [p for p in inferred if {p.first, p.second} & {asked.first, asked.second}]
    if not touching:
        return None
    pair = touching[int(rng.integers(len(touching)))]
    return pair.first, pair.second, Answer.FIRST if pair.label == 1.0 else Answer.SECOND
