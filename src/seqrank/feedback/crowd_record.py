"""What a crowd's session records beside its answers: who gave each, the answers asked of
a second person (for agreement; the closure never chains them), the reward model's
opinion of each asked pair, and how long the session took its people."""

from __future__ import annotations

from dataclasses import dataclass

from seqrank.types import Answer, AnsweredQuestion


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
