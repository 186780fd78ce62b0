"""What a crowd's session records beside its answers: who gave each, the answers asked of
a second person (for agreement; the closure never chains them), the reward model's
opinion of each asked pair, and how long the session took its people."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from seqrank.feedback.peer_reliability import GOLD
from seqrank.types import Answer, AnsweredQuestion

# an answer as reliability evidence: (first, second, answer, annotator, the model's
# P(first) before the session or None)
EvidenceRow = tuple[int, int, str, str, float | None]


@dataclass(frozen=True)
class SecondOpinion:
    """A question of someone's chain asked again of `annotator`; or, a closure check
    (`seqrank.feedback.closure_checks`), a pair the closure inferred from someone's chain,
    with `implied`: (whose chain, the answer their answers imply). `reask`: asked because
    the chain's owner was flagged before the session (`crowd_weighting` reask); the label
    that trains in place of theirs."""

    answered: AnsweredQuestion
    annotator: str
    implied: tuple[str, Answer] | None = None
    reask: bool = False


@dataclass(frozen=True)
class GoldAnswer:
    """An answer to a gold pair, a pair whose order the operator knows
    (`seqrank.labelling.gold`): `pair` names it (its stored segments' ids, outside every
    session's pool), `known` is its order and `said` the member's answer, both about `pair`
    in its order. Evidence only: a gold answer trains nothing."""

    pair: tuple[int, int]
    known: Answer
    said: Answer
    annotator: str


@dataclass(frozen=True)
class CrowdRecord:
    answered_by: tuple[str, ...]  # the annotator of each of the record's answers
    second_opinions: tuple[SecondOpinion, ...] = ()
    # the model's P(first preferred) before the session, for each answer and then each
    # second opinion; None where the model had not been fit yet
    model_first: tuple[float | None, ...] = ()
    seconds: float = 0.0  # the session's length, its people answering side by side
    person_seconds: float = 0.0  # everybody's answering time added up
    gold: tuple[GoldAnswer, ...] = ()  # answers to gold pairs given during the session

    def annotators(self) -> list[str]:
        """Everyone who answered in the session, in order of first answer."""
        seen = [*self.answered_by, *(s.annotator for s in self.second_opinions)]
        return list(dict.fromkeys(seen))


@dataclass
class SessionEvidence:
    """A crowd session's answers as reliability evidence (`CrowdRecord.evidence`)."""

    given: list[EvidenceRow] = field(default_factory=list)  # chain answers, second opinions
    implied: list[EvidenceRow] = field(default_factory=list)  # closure checks' orders
    gold: list[EvidenceRow] = field(default_factory=list)  # gold answers, and GOLD's

    def rows(self) -> list[EvidenceRow]:
        return [*self.given, *self.implied, *self.gold]


def session_evidence(
    crowd: CrowdRecord, answers: Sequence[AnsweredQuestion], place: Callable[[int], int]
) -> SessionEvidence:
    """Every answer of the session (`answers`, the chains') as evidence, segments named by
    `place` (a pool id to the caller's id): the answers given, each with the model's
    P(first); the order a closure check found implied by a chain, as its owner's answer
    (the person whose answers imply it is answerable for it); a gold answer beside the
    known order, GOLD's, under ids below every place's (a gold pair is in no pool)."""
    evidence = SessionEvidence()
    asked = [*answers, *(o.answered for o in crowd.second_opinions)]
    everyone = [*crowd.answered_by, *(o.annotator for o in crowd.second_opinions)]
    models = crowd.model_first or (None,) * len(asked)
    for a, who, model in zip(asked, everyone, models, strict=True):
        evidence.given.append((place(a.first), place(a.second), a.answer.value, who, model))
    for opinion, model in zip(crowd.second_opinions, models[len(answers) :], strict=True):
        if opinion.implied is not None:
            owner, implied = opinion.implied
            pair = place(opinion.answered.first), place(opinion.answered.second)
            evidence.implied.append((*pair, implied.value, owner, model))
    for gold in crowd.gold:
        first, second = -gold.pair[0] - 1, -gold.pair[1] - 1
        evidence.gold.append((first, second, gold.said.value, gold.annotator, None))
        evidence.gold.append((first, second, gold.known.value, GOLD, None))
    return evidence
