"""Which challenger (or pair) to ask about: uniform, disagreement or entropy (SPEC 5).

Informative choices need the reward ensemble's predicted returns of the candidate
segments, `member_returns` (members, N). For a defender d and candidate c, member m says
P_m(d > c) = sigmoid(R_m(d) - R_m(c)). `disagreement` picks the candidate with the largest
std of P_m over members, `entropy` the one whose mean P is closest to 1/2. A segment with
no defender yet (start of a chain or of a pairwise pair) is drawn uniformly.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from seqrank.feedback.schemes import Chooser, uniform_choice


def make_chooser(selection: str, member_returns: np.ndarray | None) -> Chooser:
    if selection == "uniform" or member_returns is None:
        return uniform_choice
    if selection not in ("disagreement", "entropy"):
        raise ValueError(
            f"unknown selection {selection!r}; accepted: uniform, disagreement, entropy"
        )
    returns = np.asarray(member_returns, dtype=np.float64)

    def choose(defender: int | None, available: Sequence[int], rng: np.random.Generator) -> int:
        if defender is None:
            return uniform_choice(defender, available, rng)
        candidates = np.asarray(available)
        diff = returns[:, defender : defender + 1] - returns[:, candidates]
        prob = 1.0 / (1.0 + np.exp(-np.clip(diff, -50, 50)))
        if selection == "disagreement":
            score = prob.std(axis=0)
        else:
            mean = np.clip(prob.mean(axis=0), 1e-12, 1 - 1e-12)
            score = -(mean * np.log(mean) + (1 - mean) * np.log(1 - mean))
        return int(np.argmax(score))

    return choose
