"""What a reward model gets right on held-out segments: over all of them, and at the top,
where a policy that climbs the learned reward spends its time (issue 46, item 2).

With `truth` the held-out segments' true returns and `predicted` the ensemble's mean
predicted returns (n segments):

- `accuracy`: of all pairs with unequal true returns, the fraction whose predicted returns
  are ordered the same way;
- `spearman`: the rank correlation of predicted and true returns;
- `top_accuracy`: `accuracy` among the top quarter only: the ceil(n/4) segments of highest
  true return (ties by position); None when they all have the same return;
- `top_recall`: of the ceil(n/10) segments of highest true return (the true top 10%), the
  fraction that are also among the ceil(n/10) of highest predicted return;
- `regret`: pick the best of k = 10 segments drawn at random by the predicted return; the
  regret is the true return of the truly best of the ten minus that of the one picked.
  Averaged over 1000 draws of ten (without replacement) from a fixed generator (the same
  draws for every cell), and divided by the range of the held-out true returns (their
  largest minus their smallest), so it lies in [0, 1]: 0 always picks the best, 1 would
  need a draw holding both extremes and the worst picked each time (0 when every return is
  equal).
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from scipy import stats

from seqrank.episodes import Segments

PICK_FROM = 10  # k: segments the best is picked from
PICK_DRAWS = 1000
PICK_SEED = 2046  # the draws' fixed generator (the same for every cell)
# the annotator's time under the paper's user study (supplementary D.7): the two clips
# are played, then the answer is clicked within 3 s; the clips as the labelling page
# plays them: one frame per step at its default frame rate (`seqrank label --fps`, 30)
CLIP_FPS = 30
ANSWER_SECONDS = 3.0


class ReturnModel(Protocol):
    def member_returns(self, segments: np.ndarray) -> np.ndarray: ...


def heldout_measures(model: ReturnModel, heldout: Segments) -> dict[str, float | None]:
    """Every measure of the module's docstring, of the ensemble's mean predicted return."""
    predicted = model.member_returns(heldout.features).mean(0)
    truth = heldout.rewards.sum(1)
    return {
        "accuracy": _pair_accuracy(predicted, truth),
        "spearman": float(stats.spearmanr(predicted, truth).statistic),
        "top_accuracy": top_accuracy(predicted, truth),
        "top_recall": top_recall(predicted, truth),
        "regret": pick_regret(predicted, truth),
    }


def _pair_accuracy(predicted: np.ndarray, truth: np.ndarray) -> float | None:
    """Of the pairs with unequal true returns, the fraction ordered as the truth orders
    them (None when there is no such pair)."""
    upper = np.triu_indices(len(truth), 1)
    true_sign = np.sign(truth[:, None] - truth[None, :])[upper]
    predicted_sign = np.sign(predicted[:, None] - predicted[None, :])[upper]
    strict = true_sign != 0
    return float((predicted_sign[strict] == true_sign[strict]).mean()) if strict.any() else None


def _top(values: np.ndarray, count: int) -> np.ndarray:
    """The positions of the `count` largest values (ties: the earlier position first)."""
    return np.argsort(-values, kind="stable")[:count]


def top_accuracy(predicted: np.ndarray, truth: np.ndarray) -> float | None:
    """Pair accuracy among the ceil(n/4) segments of highest true return."""
    top = _top(truth, math.ceil(len(truth) / 4))
    return _pair_accuracy(predicted[top], truth[top])


def top_recall(predicted: np.ndarray, truth: np.ndarray) -> float:
    """The share of the true top ceil(n/10) found in the predicted top ceil(n/10)."""
    count = math.ceil(len(truth) / 10)
    return len(set(_top(truth, count).tolist()) & set(_top(predicted, count).tolist())) / count


def pick_regret(
    predicted: np.ndarray,
    truth: np.ndarray,
    k: int = PICK_FROM,
    draws: int = PICK_DRAWS,
    seed: int = PICK_SEED,
) -> float:
    """The mean regret of picking the best of `k` (all of them when fewer) by `predicted`,
    over `draws` random draws, divided by the range of `truth` (module docstring)."""
    spread = float(truth.max() - truth.min())
    if spread == 0.0:
        return 0.0
    k = min(k, len(truth))
    rng = np.random.default_rng(seed)
    drawn = np.argsort(rng.random((draws, len(truth))), axis=1)[:, :k]  # k without repeats
    picked = drawn[np.arange(draws), predicted[drawn].argmax(1)]
    regret = truth[drawn].max(1) - truth[picked]
    return float(regret.mean()) / spread


def annotator_seconds(clips: int, questions: int, segment_length: int) -> float:
    """An annotator's time under the paper's user study (supplementary D.7): every new
    clip played once (`segment_length` frames at `CLIP_FPS`), plus `ANSWER_SECONDS` (3 s)
    per question to answer: segment_length / 30 x clips + 3 x questions."""
    return segment_length / CLIP_FPS * clips + ANSWER_SECONDS * questions
