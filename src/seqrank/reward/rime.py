"""RIME (Cheng et al., ICML 2024): reward learning robust to wrong preference labels.

Before every epoch the ensemble scores each labelled pair by the KL divergence between
the label and its mean predicted preference (Section 4.1, the "denoising discriminator"):

- trusted: KL below the lower bound tau_lower = -ln(rho) + alpha * rho + tau_unc, where
  rho is the largest KL of the pairs trusted before (a moving average) and
  tau_unc = min(beta_t * var_KL, 3) an uncertainty term whose weight
  beta_t = max(beta_min, beta_max - t (beta_max - beta_min) / decay_updates) decays with
  the epochs t fitted so far, over the whole run;
- flipped: KL above the upper bound -ln(tau_upper) (the model gives the label a
  probability below tau_upper): trained with the opposite label for this epoch;
- the rest is left out of this epoch.

Learned from the paper and its code (github.com/CJReinforce/RIME_ICML2024,
`reward_model_RIME.py`). Their code weights beta_t by the variance of the trusted KL
values and caps the term at 3; we do too. Where we differ: a pair both trusted and above
the upper bound is trained once, flipped (theirs trains it twice); the statistics are
updated with the pairs kept with their own label; soft labels (equal: 0.5) use the true
KL, not the cross-entropy; the learning rate has no warm-up (theirs rises linearly over
the run's first max_feedback / reward_batch x least_reward_update / 3 epochs). With no
history (rho = 0) the lower bound is large: the first epoch trusts every pair, as theirs
does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import torch

from seqrank.reward.entropy import RunningMeanStd
from seqrank.reward.model import Pairs, PlainLearner

if TYPE_CHECKING:
    from seqrank.reward.model import RewardModel

UNCERTAINTY_CAP = 3.0  # the most tau_unc adds (their `reward_model_RIME.py`)
MAX_RATE = 0.1  # the moving average's rate for rho (their RunningMeanStd(mode="fixed"))


@dataclass(frozen=True)
class RimeSettings:
    """RIME's knobs and their sources (their `run_parallel.sh` and `train_RIME.py`).

    - alpha 0.5: tau_base = -ln(rho) + alpha * rho (the paper's bound has rho / 2;
      `--threshold_alpha=0.5`).
    - beta_max 3.0, beta_min 1.0: the uncertainty weight's start and floor
      (`--threshold_beta_init=3.0 --threshold_beta_min=1.0`).
    - decay_updates 60: epochs over which beta falls from beta_max to beta_min (`k = 60`
      for DMControl in `train_RIME.py`; 600 for Meta-World).
    - tau_upper 0.001: labels the model gives a probability below this are flipped
      (`flipping_tau = 0.001`: KL above -ln 0.001 = 6.9).
    - min_epochs 17: a fit runs at least this many epochs before its accuracy may stop it.
      Their early stop (`train_RIME.py`) needs `epoch > least_reward_update` (0-based),
      with 15 for DMControl in `run_parallel.sh` (5 for Meta-World: 7). Without it a fit
      can stop after one epoch: the accuracy is measured on the labels RIME keeps or flips,
      which the model already agrees with.
    """

    alpha: float = 0.5
    beta_max: float = 3.0
    beta_min: float = 1.0
    decay_updates: int = 60
    tau_upper: float = 0.001
    min_epochs: int = 17


def kl_to_labels(p_first: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """KL(label || prediction) per pair, both Bernoulli on `first` preferred."""
    eps = 1e-8
    p = p_first.clamp(eps, 1 - eps)
    y = labels.clamp(0.0, 1.0)
    return torch.xlogy(y, y / p) + torch.xlogy(1 - y, (1 - y) / (1 - p))


class RimeThreshold:
    """The lower bound's state: rho, the trusted KL statistics and the epoch count."""

    def __init__(self, settings: RimeSettings):
        self.settings = settings
        self.rho = 0.0
        self.stats = RunningMeanStd()
        self.updates = 0

    @property
    def beta(self) -> float:
        s = self.settings
        slope = (s.beta_max - s.beta_min) / s.decay_updates
        return max(s.beta_min, s.beta_max - slope * self.updates)

    @property
    def lower(self) -> float:
        base = -math.log(self.rho + 1e-8) + self.settings.alpha * self.rho
        spread = self.stats.var if self.stats.count else 0.0
        return base + min(self.beta * spread, UNCERTAINTY_CAP)

    @property
    def upper(self) -> float:
        return -math.log(self.settings.tau_upper)

    def update(self, trusted_kl: torch.Tensor) -> None:
        """After an epoch's selection: the trusted KL values move rho and the statistics."""
        if trusted_kl.numel():
            self.rho += (float(trusted_kl.max()) - self.rho) * MAX_RATE
            self.stats.update(trusted_kl.double())
        self.updates += 1

    def state_dict(self) -> dict[str, Any]:
        return {"rho": self.rho, "stats": self.stats.state_dict(), "updates": self.updates}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.rho, self.updates = state["rho"], state["updates"]
        self.stats.load_state_dict(state["stats"])


class RimeLearner(PlainLearner):
    """The plain fit's loss on the pairs RIME keeps or flips (`reward.model.Learner`)."""

    def __init__(self, settings: RimeSettings):
        self.threshold = RimeThreshold(settings)
        self.min_epochs = settings.min_epochs
        self.last: dict[str, float] = {}

    def start_fit(self) -> None:
        self.last = {}

    def select(self, kl: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(kept, flipped) masks for the pairs' KL values; moves the threshold on."""
        lower, upper = self.threshold.lower, self.threshold.upper
        flipped = kl > upper
        kept = (kl < lower) & ~flipped
        self.last = {
            "rime_kept": float(kept.sum()),
            "rime_flipped": float(flipped.sum()),
            "rime_dropped": float((~kept & ~flipped).sum()),
            "rime_lower_bound": lower,
            "rime_beta": self.threshold.beta,
        }
        self.threshold.update(kl[kept])
        return kept, flipped

    def epoch_pairs(self, model: RewardModel, segments: torch.Tensor, pairs: Pairs) -> Pairs:
        first, second, labels = pairs
        with torch.no_grad():
            returns = model.segment_returns(segments)  # (members, S): each segment once
            p_first = torch.sigmoid(returns[:, first] - returns[:, second]).mean(0)
            kept, flipped = self.select(kl_to_labels(p_first, labels))
        use = kept | flipped
        labels = torch.where(flipped, 1 - labels, labels)
        return first[use], second[use], labels[use]

    def fit_metrics(self) -> dict[str, float]:
        """The last epoch's selection: pairs kept, flipped and left out, and its bounds."""
        return dict(self.last)

    def state_dict(self) -> dict[str, Any]:
        return self.threshold.state_dict()

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.threshold.load_state_dict(state)
