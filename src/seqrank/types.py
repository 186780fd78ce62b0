"""The data every part of seqrank exchanges, and the one label convention.

Segments are named by integer ids (indices into whatever pool a session draws from).
A label is the probability that the *first* segment of a pair is preferred:
1.0 first preferred, 0.0 second preferred, 0.5 equally preferred.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

LABEL_FIRST = 1.0
LABEL_SECOND = 0.0
LABEL_EQUAL = 0.5


class Answer(Enum):
    """A teacher's answer to "is segment `first` preferred to segment `second`?".

    What every `ask(first, second)` returns and every label comes from: FIRST and SECOND
    give labels 1.0 and 0.0, EQUAL 0.5 (never chained by transitivity), and SKIP none (the
    question still spends budget).

    Examples:
        >>> import seqrank
        >>> [answer.label for answer in seqrank.Answer]
        [1.0, 0.0, 0.5, None]
        >>> seqrank.Answer("second").flipped()
        <Answer.FIRST: 'first'>
    """

    FIRST = "first"
    SECOND = "second"
    EQUAL = "equal"
    SKIP = "skip"

    @property
    def label(self) -> float | None:
        """Soft label for the first segment; None when the pair carries no label (skip)."""
        return _ANSWER_LABEL[self]

    def flipped(self) -> Answer:
        """The same answer with the two segments swapped (used to map a shown order back)."""
        return _FLIPPED.get(self, self)


_ANSWER_LABEL: dict[Answer, float | None] = {
    Answer.FIRST: LABEL_FIRST,
    Answer.SECOND: LABEL_SECOND,
    Answer.EQUAL: LABEL_EQUAL,
    Answer.SKIP: None,
}
_FLIPPED = {Answer.FIRST: Answer.SECOND, Answer.SECOND: Answer.FIRST}


@dataclass(frozen=True)
class Question:
    """One question asked in a session: `first` is the defender when there is one."""

    index: int
    first: int
    second: int
    first_is_defender: bool


@dataclass(frozen=True)
class AnsweredQuestion:
    question: Question
    answer: Answer

    @property
    def first(self) -> int:
        return self.question.first

    @property
    def second(self) -> int:
        return self.question.second


@dataclass(frozen=True)
class LabelledPair:
    """A pair the reward model trains on. `inferred` pairs come from transitivity."""

    first: int
    second: int
    label: float
    inferred: bool
