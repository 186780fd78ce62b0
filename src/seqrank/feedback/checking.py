"""Noise-aware augmentation (`augment checked`): re-check the answers that would move much.

With a perfect teacher every answer can be chained; with a noisy one, a single wrong answer
that the closure chains (root's challenger wrongly beating the root places it above the
whole tree) turns into many wrong labels. Three parts work together:

- in the session, an answer whose transitive closure would add at least `gain` new pairs
  is asked again; it stands only if every repeat agrees, otherwise the scheme treats the
  question as skipped and the closure sees a pair whose answers disagree (no edge, or an
  unconfirmed one). Once the teacher has contradicted themselves (a repeat that disagreed,
  in this session or an earlier one of the run), an answer that would imply `twice_gain`
  pairs or more is asked twice more: a teacher who has never disagreed with themselves
  is asked once, which is what a perfect teacher costs;
- once a reward model has been fit, it is a second opinion for a teacher who has never
  contradicted themselves: an answer the model agrees with (ranks the pair the same way)
  is not asked again and counts as confirmed in the closure; one it disagrees with is
  asked again as above. A teacher who has contradicted themselves is asked again
  whatever the model says;
- in the closure, a pair is inferred only along a path with at most `path_unchecked`
  edges that rest on one unconfirmed answer (`augment(..., path_unchecked=...)`).

Each repeat spends a question of the session's budget, which is what it trades: with the
oracle teacher root keeps about 1.74 pairs per question instead of 1.84, while under B-Pref's
`mistake` teacher (10% flipped answers) inferred labels go from about 3 times to fewer than
the teacher's own errors (`seqrank simulate --augment full,checked`). Repeats assume a
teacher's errors on the same pair are independent, as in B-Pref's scripted teachers; a
person who misjudges a pair may misjudge it again.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace

from seqrank.feedback.closure import augment
from seqrank.types import Answer, AnsweredQuestion


@dataclass(frozen=True)
class Recheck:
    """Noise-aware augmentation's settings (`--augment checked`): which answers to ask again.

    An answer whose transitive closure would add at least `gain` new pairs is asked again
    within the session's budget and stands only if every repeat agrees (the module says
    why). `run_scheme(..., recheck=Recheck())` applies it to a session, and
    `TrainConfig.recheck` is a run's. ValueError unless 1 <= gain <= twice_gain and
    path_unchecked >= 0.

    Attributes:
        gain: ask again an answer that would imply at least this many new pairs (default
            1: any answer that implies a pair).
        twice_gain: from this many (default 5), ask twice more once the teacher has
            contradicted themselves.
        path_unchecked: unconfirmed answers allowed on a path that a pair is inferred
            along (default 1), for `close_preferences(..., path_unchecked=...)`.
        contradicted: the teacher contradicted themselves in an earlier session of the
            run (default False; `after` sets it).
        model_returns: a fitted reward model's predicted return of each pooled segment: an
            answer it agrees with is not asked again of a teacher who never contradicted
            themselves, and lands in `SessionRecord.vouched`; None (default): no model.

    Examples:
        >>> import seqrank
        >>> value = [3.0, 1.0, 2.0, 5.0, 4.0, 0.5, 2.5]
        >>> def ask(first, second):
        ...     better = value[first] > value[second]
        ...     return seqrank.Answer.FIRST if better else seqrank.Answer.SECOND
        >>> recheck = seqrank.Recheck()
        >>> record = seqrank.run_scheme("sequential", 7, 6, ask, recheck=recheck)
        >>> record.asked, len({(q.first, q.second) for q in record.answers})  # one repeat
        (6, 5)
        >>> recheck.after(record.answers).contradicted  # the repeat agreed
        False
    """

    gain: int = 1  # re-ask an answer that would imply at least this many new pairs
    # ... twice from this many on, once the teacher has contradicted themselves. Why 5 (not
    # 20, the first choice): a wrong win that one repeat confirms (two slips) puts the
    # challenger above the whole tree; with sessions of 25 questions, as in the reward
    # benchmark, 20 left root's inferred labels 14% wrong under `mistake` (asked: 9%), 5
    # brings them to 6%. Why only once contradicted: asked of every teacher, the second
    # repeat cost root's oracle pairs per question 1.74 -> 1.64 in 50-question sessions
    # (results/noise-aware/README.md).
    twice_gain: int = 5
    path_unchecked: int = 1  # unconfirmed edges allowed on an inference path
    # whether the teacher contradicted themselves in an earlier session of the run (the
    # run's loop sets it: `after`, or `contradicts_itself` over its stored questions)
    contradicted: bool = False
    # the reward model's predicted return of each of the session's segments, once it has
    # been fit (`prepare_session` sets it; None: no model yet, or none at hand)
    model_returns: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.gain < 1 or self.twice_gain < self.gain or self.path_unchecked < 0:
            raise ValueError(
                f"recheck settings gain {self.gain}, twice_gain {self.twice_gain}, "
                f"path_unchecked {self.path_unchecked}: need 1 <= gain <= twice_gain "
                "and path_unchecked >= 0"
            )

    def repeats(self, answers: Sequence[AnsweredQuestion]) -> int:
        """How many more times to ask the last of `answers`: by how many new pairs the
        paper's closure would infer if it were trusted."""
        return self.decide(answers)[0]

    def decide(self, answers: Sequence[AnsweredQuestion]) -> tuple[int, bool]:
        """(repeats, spared) for the last of `answers`: spared when it would have been
        asked again but the fitted model agrees with it (then it is vouched for)."""
        if answers[-1].answer not in (Answer.FIRST, Answer.SECOND):
            return 0, False
        gain = augment(answers).stats.inferred - augment(answers[:-1]).stats.inferred
        if gain < self.gain:
            return 0, False
        contradicted = self.contradicted or contradicts_itself(_asked(answers))
        if not contradicted and self.model_agrees(answers[-1]):
            return 0, True
        if gain < self.twice_gain:
            return 1, False
        return (2 if contradicted else 1), False

    def model_agrees(self, answer: AnsweredQuestion) -> bool:
        """Whether the fitted reward model ranks the pair as the teacher did (a tie is
        not agreement); False while there is no model."""
        if self.model_returns is None:
            return False
        first, second = self.model_returns[answer.first], self.model_returns[answer.second]
        return first > second if answer.answer is Answer.FIRST else second > first

    def after(self, answers: Sequence[AnsweredQuestion]) -> Recheck:
        """These settings for the teacher's next session, given this session's answers
        (without this session's model opinions, which index its own pool)."""
        contradicted = self.contradicted or contradicts_itself(_asked(answers))
        return replace(self, contradicted=contradicted, model_returns=None)


def standing_vouched(
    answers: Sequence[AnsweredQuestion], vouched: frozenset[tuple[int, int]]
) -> frozenset[tuple[int, int]]:
    """The vouched (winner, loser) edges the closure may take as confirmed: none once the
    session holds a contradiction, since the trust was in a teacher who had none."""
    return frozenset() if contradicts_itself(_asked(answers)) else vouched


def contradicts_itself(asked: Iterable[tuple[int, int, Answer]]) -> bool:
    """Whether two answers to the same pair of segments (first, second, answer), in either
    order, disagree. Skips are not answers: a repeat the teacher skips (or lets time out)
    drops the answer it was to confirm but is not taken for a contradiction."""
    seen: dict[tuple[int, int], Answer] = {}
    for first, second, answer in asked:
        if answer is Answer.SKIP:
            continue
        key, answer = (
            ((first, second), answer) if first < second else ((second, first), answer.flipped())
        )
        if seen.setdefault(key, answer) is not answer:
            return True
    return False


def _asked(answers: Iterable[AnsweredQuestion]) -> Iterable[tuple[int, int, Answer]]:
    return ((a.first, a.second, a.answer) for a in answers)


def confirmed_answer(
    answers: list[AnsweredQuestion],
    repeats: int,
    ask_again: Callable[[], Answer],
    budget_left: Callable[[], int],
) -> Answer:
    """The last answer if its `repeats` (asked while budget is left) all agree with it;
    SKIP when one disagrees. Repeats are appended to `answers` by `ask_again`."""
    first = answers[-1].answer
    for _ in range(repeats):
        if budget_left() <= 0:
            break
        if ask_again() is not first:
            return Answer.SKIP
    return first
