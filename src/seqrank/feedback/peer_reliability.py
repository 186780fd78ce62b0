"""Each person's reliability from the other people's answers alone, shrunk towards the
crowd's mean (issue 49): the estimator a crowd's flags and labels use by default.

The model is `reliability.py`'s one-coin Dawid-Skene model, with two changes that the
benchmark (`results/crowd/`) asked for:
- the reward model does not vote. At the budgets a crowd answers it is weak (about 0.7 on
  held-out pairs), and on a pair one person and the model answered, a disagreement cannot
  say which of the two is wrong: it dragged a never-wrong member down to 0.8;
- each estimate is shrunk towards the crowd's mean, a Beta prior of `PRIOR_ANSWERS`
  answers centred on the share of all the people's answers expected right (hierarchical
  shrinkage, an empirical-Bayes prior): a member nothing sets apart stays with the crowd
  instead of at 1/2, and few answers cannot make a good member look bad.
Gold answers (a pair whose order the operator knows, shown unannounced) are one more
opinion, that of `GOLD`, always right: they count against whoever contradicts them.
An answer the closure of someone's chain implies (`SecondOpinion.implied`) counts as that
person's answer: the person whose answers imply it is answerable for it.

The interval is a 95% percentile bootstrap over the pairs: a Beta posterior that counts
the expected right answers as observed covered the true reliability only 80% of the time
(the truth of a pair two people disagree on is itself uncertain); its coverage is measured
in tests/feedback/test_peer_reliability.py. It is never narrower than that Beta interval
(Jeffreys') on the answers it rests on: where everybody agrees, the bootstrap has nothing
to resample and would say 0.98 [0.977, 0.981] after 32 checks.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import beta as beta_distribution

from seqrank.feedback.reliability import (
    ITERATIONS,
    START,
    Evidence,
    Reliability,
    agreement,
    posterior,
)

GOLD = "(gold)"  # the operator's known order as an opinion (no annotator's name has brackets)
GOLD_RELIABILITY = 1.0 - 1e-3  # (as certain as the posterior's clipping allows)
PRIOR_ANSWERS = 2.0  # answers' worth of the crowd's mean in every estimate
FLAG_BELOW = 0.84  # a person estimated below this is flagged ...
FLAG_AFTER = 20  # ... once the estimate rests on this many answers checked by others
RESAMPLES = 200  # bootstrap draws of the pairs for the interval
TOLERANCE = 1e-6  # EM stops once no reliability moves more than this


@dataclass(frozen=True)
class _Votes:
    """The informative opinions: voter, pair and answer of each, sorted by pair."""

    who: np.ndarray
    item: np.ndarray
    said: np.ndarray
    pairs: int
    people: int  # voters 0 .. people - 1 are people; `people` is GOLD

    def resampled(self, rng: np.random.Generator) -> _Votes:
        """The votes of as many pairs drawn with replacement."""
        counts = np.bincount(self.item, minlength=self.pairs)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        drawn = rng.integers(self.pairs, size=self.pairs)
        lengths = counts[drawn]
        first = np.repeat(starts[drawn] - np.concatenate([[0], np.cumsum(lengths)[:-1]]), lengths)
        rows = first + np.arange(lengths.sum())
        item = np.repeat(np.arange(self.pairs), lengths)
        return _Votes(self.who[rows], item, self.said[rows], self.pairs, self.people)


def estimate_from_peers(
    evidence: Sequence[Evidence], seed: int = 0, resamples: int = RESAMPLES
) -> dict[str, Reliability]:
    """Each person's reliability, in order of first answer; the reward model's opinions in
    `evidence` are not used, and `GOLD`'s answers are evidence, not a person. The interval
    is a percentile bootstrap over pairs (`resamples` draws, seeded by `seed`): the
    truth of a pair two people disagree on is uncertain, which a count of answers alone
    does not say."""
    names = list(dict.fromkeys(e.annotator for e in evidence if e.annotator != GOLD))
    votes = _informative(evidence, names)
    estimate, answers, _ = _fit(votes)
    rng = np.random.default_rng(seed)
    draws = np.array(
        [_fit(votes.resampled(rng))[0] for _ in range(resamples if votes.pairs else 0)]
    )
    return {
        name: _summary(name, k, estimate[k], int(answers[k]), draws, votes)
        for k, name in enumerate(names)
    }


def _informative(evidence: Sequence[Evidence], names: list[str]) -> _Votes:
    """The opinions on pairs with two or more, sorted by pair."""
    opinions = Counter(e.pair for e in evidence)
    informative = sorted((e for e in evidence if opinions[e.pair] > 1), key=lambda e: e.pair)
    pairs = {pair: k for k, pair in enumerate(dict.fromkeys(e.pair for e in informative))}
    voters = [*names, GOLD]
    return _Votes(
        np.array([voters.index(e.annotator) for e in informative], dtype=np.int64),
        np.array([pairs[e.pair] for e in informative], dtype=np.int64),
        np.array([e.said_first for e in informative], dtype=bool),
        len(pairs),
        len(names),
    )


def _fit(votes: _Votes) -> tuple[np.ndarray, np.ndarray, float]:
    """(each person's reliability, the answers it rests on, the crowd's mean) by EM."""
    people = votes.who < votes.people
    answers = np.bincount(votes.who[people], minlength=votes.people).astype(float)
    p: np.ndarray = np.full(votes.people + 1, START)
    p[-1] = GOLD_RELIABILITY
    mean = START
    for _ in range(ITERATIONS if votes.pairs else 0):
        truth_first = posterior(votes.pairs, votes.item, votes.who, votes.said, p)
        right = np.where(votes.said, truth_first[votes.item], 1.0 - truth_first[votes.item])
        counted = np.bincount(votes.who[people], weights=right[people], minlength=votes.people)
        mean = float(counted.sum() / answers.sum()) if answers.sum() else START
        shrunk = (counted + PRIOR_ANSWERS * mean) / (answers + PRIOR_ANSWERS)
        moved = float(np.max(np.abs(shrunk - p[:-1]), initial=0.0))
        p[:-1] = shrunk
        if moved < TOLERANCE:
            break
    return p[:-1], answers, mean


def _summary(
    name: str, k: int, estimate: float, answers: int, draws: np.ndarray, votes: _Votes
) -> Reliability:
    low, high = (0.0, 1.0) if not len(draws) else np.quantile(draws[:, k], [0.025, 0.975])
    if answers:  # never narrower than the answers it rests on allow (`_counts_interval`)
        counts_low, counts_high = _counts_interval(estimate, answers)
        low, high = min(low, counts_low), max(high, counts_high)
    agreeing, overlapping = agreement(k, votes.who, votes.item, votes.said, model=-1)
    return Reliability(
        name,
        float(estimate),
        float(min(low, estimate)),
        float(max(high, estimate)),
        answers,
        overlapping,
        agreeing / overlapping if overlapping else None,
        flag_below=FLAG_BELOW,
        flag_after=FLAG_AFTER,
    )


def _counts_interval(estimate: float, answers: int) -> tuple[float, float]:
    """The 95% interval of a share right out of `answers` (Jeffreys' Beta): a bootstrap of
    answers that all agree collapses to a point, which would read as near-proof on the
    operator's page after a few dozen checks."""
    right = estimate * answers
    counts = beta_distribution(right + 0.5, answers - right + 0.5)
    return float(counts.ppf(0.025)), float(counts.ppf(0.975))
