"""Where a team's question or choice sits in its session, and the index it is stored under.

The `questions` and `choices` tables key a session's rows by one integer. A team's row
is a `ChainStep` (the k-th question, or choice, of a chain) or a `SecondOpinionOf` (the
`nth` other opinion on a chain's question); `index` and `key_of` are the one encoding
between them and the integer: `chain * CHAIN_STRIDE + k`, and `-(index + 1)` for the first
other opinion, as every stored team session already holds them; the next ones (asked while
a member's evidence is short, `seqrank.feedback.overlap`) `OPINION_STRIDE` further down.
"""

from __future__ import annotations

from dataclasses import dataclass

CHAIN_STRIDE = 100_000  # questions (or choices) a chain may make in one session
SECOND_OPINIONS = -1  # the chain a second opinion is stored under in `crowd_questions`
GOLD_CHECKS = -2  # ... and a gold question (`seqrank.labelling.gold`)
GOLD_RUN = "(gold)"  # the run gold segments and questions are stored under (no run's name)
OPINION_STRIDE = 10**12  # between the nth and the (n+1)th opinions' indices (SQLite: 2**63)
REASK_NTH = 2  # a re-ask's opinion index: stored, so fixed; above the overlap's (0, 1)


@dataclass(frozen=True)
class ChainStep:
    """The k-th question (or choice) of chain `chain`."""

    chain: int
    k: int

    def __post_init__(self) -> None:
        if self.chain < 0 or not 0 <= self.k < CHAIN_STRIDE:
            raise ValueError(f"no chain step {self.k} of chain {self.chain}")

    @property
    def index(self) -> int:
        return self.chain * CHAIN_STRIDE + self.k


@dataclass(frozen=True)
class SecondOpinionOf:
    """Another person's opinion on the chain question `asked`: the first (`nth` 0), or the
    next ones."""

    asked: ChainStep
    nth: int = 0

    def __post_init__(self) -> None:
        if self.nth < 0 or self.asked.index >= OPINION_STRIDE:
            raise ValueError(f"no opinion {self.nth} on chain question {self.asked.index}")

    @property
    def index(self) -> int:
        return -(self.nth * OPINION_STRIDE + self.asked.index + 1)


QuestionKey = ChainStep | SecondOpinionOf


def key_of(index: int) -> QuestionKey:
    """The key a stored index encodes."""
    if index < 0:
        nth, asked = divmod(-index - 1, OPINION_STRIDE)
        return SecondOpinionOf(_step(asked), nth)
    return _step(index)


def _step(index: int) -> ChainStep:
    chain, k = divmod(index, CHAIN_STRIDE)
    return ChainStep(chain, k)
