"""How far each annotator of a crowd can be trusted, estimated from their answers.

The model (a "one-coin" Dawid-Skene model, Dawid and Skene 1979):
- annotator j answers a strict question rightly with probability p_j, whatever the pair;
- the reward model, as it was before the session that asked a pair, is one more voter on
  the pair (it prefers the segment it predicts the larger return for), with a reliability
  of its own: its raw probabilities are over-confident after few labels, its vote is not;
- the opinions on one pair (an overlap asks it of two people, a re-check twice of one, and
  the model has its vote from the second session on) are independent given the truth,
  whose prior is 1/2.
Expectation-maximisation alternates the posterior of each pair's truth given its opinions
with p_j = the share of j's answers expected right. A pair only one opinion speaks for says
nothing about anyone's reliability and is left out. The model's own reliability is
measured on the pairs two people or more answered (with a prior of 0.8 worth four pairs):
on a pair only one person and the model speak for, a disagreement cannot say which of the
two is wrong, and letting those pairs move it lets every person drift to "always right".
Three things inform the estimate, as the issue asks: overlaps (two people on one pair),
contradictions (one person's answers to one pair that disagree) and the reward model's
agreement with each person. The estimate is the mean and the interval the 95% interval of
the Beta posterior (from a uniform prior) that counts the expected right answers as
observed: the interval says how many answers the estimate rests on, not how wrong the
model may be. Where the model is weak (sequential and root sessions cut few distinct
segments) and few pairs are overlapped, the data cannot tell people apart and every
estimate drifts high: `results/crowd/` measures when it can.

Why this model: it needs no gold questions, it works with the model alone when nobody
overlaps, and its estimate is what reward training needs: the probability that an answer
is right (`soft_label`).
"""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import beta as beta_distribution

START = 0.8  # every voter's reliability before the first iteration
ITERATIONS = 50
FLAG_BELOW = 0.7  # an annotator estimated below this is flagged (never dropped) ...
FLAG_AFTER = 20  # ... once the estimate rests on this many answers
MODEL = "(model)"  # the reward model's name as a voter (no annotator's name has brackets)
MODEL_PRIOR = 4  # pairs' worth of belief in the model's START reliability


@dataclass(frozen=True)
class Evidence:
    """One strict answer: `pair` names the pair (the same for every answer to it),
    `said_first` whether the annotator preferred the pair's first segment, `model_first`
    the model's P(first) before the session (None before its first fit)."""

    pair: tuple[int, int]
    annotator: str
    said_first: bool
    model_first: float | None


@dataclass(frozen=True)
class Reliability:
    annotator: str
    estimate: float  # P(a strict answer of theirs is right)
    low: float  # the 95% interval
    high: float
    answers: int  # strict answers it rests on (on pairs with another opinion)
    overlaps: int  # of them, on pairs somebody else answered too
    agreement: float | None  # share of those agreeing with the other answers (None: none)
    flag_below: float = FLAG_BELOW  # the estimator's flag rule
    flag_after: int = FLAG_AFTER

    @property
    def flagged(self) -> bool:
        return self.answers >= self.flag_after and self.estimate < self.flag_below


def estimate_reliability(evidence: Sequence[Evidence]) -> dict[str, Reliability]:
    """Each annotator's reliability, in order of first answer (the reward model's under
    `MODEL`, when it voted)."""
    votes = _with_model_votes(evidence)
    names = list(dict.fromkeys(e.annotator for e in votes))
    if not names:
        return {}
    opinions = Counter(e.pair for e in votes)
    informative = [e for e in votes if opinions[e.pair] > 1]
    pairs = list(dict.fromkeys(e.pair for e in informative))
    pair_index = {pair: k for k, pair in enumerate(pairs)}
    who = np.array([names.index(e.annotator) for e in informative], dtype=np.int64)
    item = np.array([pair_index[e.pair] for e in informative], dtype=np.int64)
    said = np.array([e.said_first for e in informative], dtype=bool)
    # the model's reliability is measured on pairs two people or more answered: where only
    # one person and the model speak, "they disagree" cannot say which of them is wrong
    model = names.index(MODEL) if MODEL in names else -1
    people_on = np.bincount(item[who != model], minlength=len(pairs))
    counts = (who != model) | (people_on[item] >= 2)
    answers = np.bincount(who[counts], minlength=len(names))
    p: np.ndarray = np.full(len(names), START)
    counted: np.ndarray = np.zeros(len(names))
    for _ in range(ITERATIONS if len(informative) else 0):
        truth_first = posterior(len(pairs), item, who, said, p)
        right = np.where(said, truth_first[item], 1.0 - truth_first[item])
        counted = np.bincount(who[counts], weights=right[counts], minlength=len(names))
        p = np.where(answers > 0, counted / np.maximum(answers, 1), START)
        if model >= 0:  # (a prior of MODEL_PRIOR pairs at START: few overlaps, little news)
            p[model] = (counted[model] + START * MODEL_PRIOR) / (answers[model] + MODEL_PRIOR)
    return {
        name: _summary(name, k, counted, answers, who[counts], item[counts], said[counts], model)
        for k, name in enumerate(names)
    }


def _with_model_votes(evidence: Sequence[Evidence]) -> list[Evidence]:
    """The people's answers, and the model's vote on each pair it had an opinion of."""
    model: dict[tuple[int, int], list[float]] = defaultdict(list)
    for e in evidence:
        if e.model_first is not None:
            model[e.pair].append(e.model_first)
    votes = [Evidence(pair, MODEL, float(np.mean(p)) > 0.5, None) for pair, p in model.items()]
    return [*evidence, *votes]


def posterior(
    pairs: int, item: np.ndarray, who: np.ndarray, said: np.ndarray, p: np.ndarray
) -> np.ndarray:
    """P(first preferred | the pair's opinions) of every pair, from a prior of 1/2 (sums
    of logs, so that many opinions on one pair do not underflow)."""
    clipped = np.clip(p[who], 1e-3, 1 - 1e-3)
    log_if_first = np.where(said, np.log(clipped), np.log1p(-clipped))
    log_if_second = np.where(said, np.log1p(-clipped), np.log(clipped))
    first = np.bincount(item, weights=log_if_first, minlength=pairs)
    second = np.bincount(item, weights=log_if_second, minlength=pairs)
    return 1.0 / (1.0 + np.exp(np.clip(second - first, -700, 700)))


def _summary(
    name: str,
    k: int,
    counted: np.ndarray,
    answers: np.ndarray,
    who: np.ndarray,
    item: np.ndarray,
    said: np.ndarray,
    model: int,
) -> Reliability:
    right, n = float(counted[k]), int(answers[k])
    posterior = beta_distribution(right + 1.0, n - right + 1.0)
    agreeing, overlapping = agreement(k, who, item, said, model)
    return Reliability(
        name,
        (right + 1.0) / (n + 2.0),
        float(posterior.ppf(0.025)),
        float(posterior.ppf(0.975)),
        n,
        overlapping,
        agreeing / overlapping if overlapping else None,
    )


def agreement(
    k: int, who: np.ndarray, item: np.ndarray, said: np.ndarray, model: int
) -> tuple[int, int]:
    """(agreeing, compared): annotator k's answers on pairs another person answered (the
    model's vote is not a person's), and how many agree with every other person's."""
    others: dict[int, list[bool]] = defaultdict(list)
    for person, pair, first in zip(who, item, said, strict=True):
        if person != k and person != model:
            others[int(pair)].append(bool(first))
    shared = [
        (int(pair), bool(first))
        for person, pair, first in zip(who, item, said, strict=True)
        if person == k and int(pair) in others
    ]
    agreeing = sum(all(o == first for o in others[pair]) for pair, first in shared)
    return agreeing, len(shared)


def soft_label(label: float, reliability: Reliability) -> float:
    """A label as the probability that it is right: an answer "first" of an annotator right
    with probability p trains towards P(first) = p (p below 1/2 counts as 1/2: no
    information, never flipped); equal answers stay 1/2, and so does every answer of an
    annotator nothing is known of yet."""
    if reliability.answers == 0:
        return label
    trust = min(max(reliability.estimate, 0.5), 1.0)
    return 0.5 + (label - 0.5) * (2.0 * trust - 1.0)


def evidence_rows(rows: Iterable[tuple[int, int, str, str, float | None]]) -> list[Evidence]:
    """Evidence from stored answers (first, second, answer, annotator, the model's
    P(first)): a pair is the same whichever way round it was asked, and equal and skipped
    answers say nothing about being right."""
    evidence = []
    for first, second, answer, annotator, model in rows:
        if answer not in ("first", "second"):
            continue
        said_first = answer == "first"
        if first < second:
            evidence.append(Evidence((first, second), annotator, said_first, model))
        else:  # one key for both orders
            flipped = None if model is None else 1.0 - model
            evidence.append(Evidence((second, first), annotator, not said_first, flipped))
    return evidence
