"""How far each annotator of a crowd can be trusted, estimated from their answers.

The model (a "one-coin" Dawid-Skene model, Dawid and Skene 1979, with the reward model as
the prior of each pair's truth):
- annotator j answers a strict question rightly with probability p_j, whatever the pair;
- the truth of a pair is unknown; its prior is the reward model's P(first preferred)
  before the session that asked it (clipped to [0.05, 0.95], so that a confident model
  cannot outvote people; 1/2 before the model's first fit);
- the answers to one pair (an overlap asks it of two people, a re-check twice of one) are
  independent given its truth.
Expectation-maximisation alternates the posterior of each pair's truth given its answers
and prior with p_j = (right answers expected + 1) / (answers + 2) (the mean of a Beta
posterior from a uniform prior). Three things inform it, as the issue asks: overlaps (two
people on one pair), contradictions (one person's answers to one pair that disagree) and
the model's agreement with each person. The interval is the 95% interval of that Beta
posterior, counting the expected right answers as observed, so it says how many answers
the estimate rests on, not how wrong the model may be.

Why this model: it needs no gold questions, it degrades to the model's agreement when
nobody overlaps, and its estimate is directly what reward training needs: the
probability that an answer is right (`soft_label`).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import beta as beta_distribution

PRIOR_CLIP = (0.05, 0.95)
START = 0.8  # every annotator's reliability before the first iteration
ITERATIONS = 50
FLAG_BELOW = 0.7  # an annotator estimated below this is flagged (never dropped)


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
    answers: int  # strict answers it rests on
    overlaps: int  # of them, on pairs somebody else answered too
    agreement: float | None  # share of those agreeing with the other answers (None: none)

    @property
    def flagged(self) -> bool:
        return self.estimate < FLAG_BELOW


def estimate_reliability(evidence: Sequence[Evidence]) -> dict[str, Reliability]:
    """Each annotator's reliability, in order of first answer."""
    names = list(dict.fromkeys(e.annotator for e in evidence))
    if not names:
        return {}
    pairs = list(dict.fromkeys(e.pair for e in evidence))
    pair_index = {pair: k for k, pair in enumerate(pairs)}
    who = np.array([names.index(e.annotator) for e in evidence])
    item = np.array([pair_index[e.pair] for e in evidence])
    said = np.array([e.said_first for e in evidence])
    prior = _prior(evidence, item, len(pairs))
    p = np.full(len(names), START)
    for _ in range(ITERATIONS):
        truth_first = _posterior(prior, item, who, said, p)
        right = np.where(said, truth_first[item], 1.0 - truth_first[item])
        counted = np.bincount(who, weights=right, minlength=len(names))
        answers = np.bincount(who, minlength=len(names))
        p = (counted + 1.0) / (answers + 2.0)
    return {
        name: _summary(name, k, counted, answers, who, item, said) for k, name in enumerate(names)
    }


def _prior(evidence: Sequence[Evidence], item: np.ndarray, count: int) -> np.ndarray:
    """Each pair's P(first preferred) before its answers: the model's, averaged over the
    answers that carry it (an overlap carries it twice)."""
    total, seen = np.zeros(count), np.zeros(count)
    for k, e in enumerate(evidence):
        if e.model_first is not None:
            total[item[k]] += e.model_first
            seen[item[k]] += 1
    prior = np.where(seen > 0, total / np.maximum(seen, 1), 0.5)
    return np.clip(prior, *PRIOR_CLIP)


def _posterior(
    prior: np.ndarray, item: np.ndarray, who: np.ndarray, said: np.ndarray, p: np.ndarray
) -> np.ndarray:
    """P(first preferred | the pair's answers) of every pair (in logs, for long runs)."""
    clipped = np.clip(p[who], 1e-6, 1 - 1e-6)
    log_if_first = np.where(said, np.log(clipped), np.log1p(-clipped))
    log_if_second = np.where(said, np.log1p(-clipped), np.log(clipped))
    first = np.log(prior) + np.bincount(item, weights=log_if_first, minlength=len(prior))
    second = np.log1p(-prior) + np.bincount(item, weights=log_if_second, minlength=len(prior))
    return 1.0 / (1.0 + np.exp(np.clip(second - first, -700, 700)))


def _summary(
    name: str,
    k: int,
    counted: np.ndarray,
    answers: np.ndarray,
    who: np.ndarray,
    item: np.ndarray,
    said: np.ndarray,
) -> Reliability:
    right, n = float(counted[k]), int(answers[k])
    posterior = beta_distribution(right + 1.0, n - right + 1.0)
    agreeing, overlapping = _agreement(k, who, item, said)
    return Reliability(
        name,
        (right + 1.0) / (n + 2.0),
        float(posterior.ppf(0.025)),
        float(posterior.ppf(0.975)),
        n,
        overlapping,
        agreeing / overlapping if overlapping else None,
    )


def _agreement(k: int, who: np.ndarray, item: np.ndarray, said: np.ndarray) -> tuple[int, int]:
    """(agreeing, compared): annotator k's answers on pairs somebody else answered, and
    how many of them agree with every other person's answer to the pair."""
    others: dict[int, list[bool]] = defaultdict(list)
    for person, pair, first in zip(who, item, said, strict=True):
        if person != k:
            others[int(pair)].append(bool(first))
    shared = [
        (int(pair), bool(first))
        for person, pair, first in zip(who, item, said, strict=True)
        if person == k and int(pair) in others
    ]
    agreeing = sum(all(o == first for o in others[pair]) for pair, first in shared)
    return agreeing, len(shared)


def soft_label(label: float, reliability: float) -> float:
    """A label as the probability that it is right: an answer "first" of an annotator right
    with probability p trains towards P(first) = p (p below 1/2 counts as 1/2: no
    information, never flipped); equal answers stay 1/2."""
    trust = min(max(reliability, 0.5), 1.0)
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
