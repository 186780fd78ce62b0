"""SURF (Park et al., ICLR 2022): semi-supervised reward learning with data augmentation.

Two additions to the Bradley-Terry fit, learned from the paper and its code
(github.com/alinlab/SURF, `reward_model_semi_dataaug.py`):

- pseudo-labels: before each fit, unlabelled segment pairs are cut from the kept episodes;
  each minibatch of labelled pairs comes with `unlabelled_batch` times as many unlabelled
  ones, which each member labels with its own predicted preference on the whole segments.
  Only the pairs it predicts with confidence of at least `threshold` enter the loss, with
  weight `loss_weight` (the paper's semi-supervised loss, Section 4.1).
- temporal cropping: each pair in a loss (labelled or pseudo-labelled) is compared on
  sub-segments of one random length, each at its own random start (Section 4.2).

Where this differs from their code: their segments are cut `2 * window` steps longer than
the teacher sees and cropped to H +- 5 steps; ours are exactly what the teacher (or the
person) saw, so a crop is a sub-segment of length H - `crop` to H. Their unlabelled pairs
accumulate in a buffer over the run, `inv_label_ratio` of them per question asked; ours
are as many, drawn afresh for each fit from the kept episodes (by the run seed and
session: nothing to checkpoint), so later fits also see pairs from the recent policy.
The unlabelled batch is drawn at random (with replacement) per member and step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
import torch.nn.functional as F

from seqrank.reward.model import PlainLearner

if TYPE_CHECKING:
    from seqrank.reward.model import RewardModel


@dataclass(frozen=True)
class SurfSettings:
    """SURF's knobs and their sources.

    - threshold 0.99: the confidence a pseudo-label needs (`threshold_u`; 0.99 in the
      README's DMC and Meta-World commands and the RIME authors' `run_parallel.sh`; their
      yaml default is 0.95).
    - unlabelled_ratio 10: unlabelled pairs per question asked so far (`inv_label_ratio`;
      `config/train_PEBBLE_semi_dataaug.yaml` and the Meta-World command; 100 in the
      walker command, which asks 10 questions a session).
    - unlabelled_batch 4: unlabelled pairs per labelled pair in a minibatch (`mu`; 4 in
      the README's commands; yaml default 1).
    - loss_weight 1.0: weight of the pseudo-label loss (`lambda_u`, yaml).
    - crop 5: a crop is up to this many steps shorter than the segment (`crop_range`,
      yaml; see the module's note on how ours differs).
    """

    threshold: float = 0.99
    unlabelled_ratio: int = 10
    unlabelled_batch: int = 4
    loss_weight: float = 1.0
    crop: int = 5


def crop_masks(
    shape: tuple[int, ...], horizon: int, crop: int, generator: torch.Generator
) -> tuple[torch.Tensor, torch.Tensor]:
    """Masks (*shape, horizon) of two crops per pair: one length in [horizon - crop,
    horizon] per pair, each segment's start uniform where the crop fits."""
    crop = min(crop, horizon - 1)
    lengths = horizon - torch.randint(0, crop + 1, shape, generator=generator)
    steps = torch.arange(horizon)
    masks = []
    for _ in range(2):
        room = (horizon - lengths + 1).double()
        start = (torch.rand(shape, generator=generator, dtype=torch.float64) * room).long()
        inside = (steps >= start[..., None]) & (steps < (start + lengths)[..., None])
        masks.append(inside.float())
    return masks[0], masks[1]


def pseudo_labels(logits: torch.Tensor, threshold: float) -> tuple[torch.Tensor, torch.Tensor]:
    """(labels, used) from a member's logits of unlabelled pairs: the predicted preference
    (1.0: the first) and whether its confidence reaches `threshold`."""
    p_first = torch.sigmoid(logits)
    confidence = torch.maximum(p_first, 1 - p_first)
    return (p_first > 0.5).float(), confidence >= threshold


class SurfLearner(PlainLearner):
    """The plain fit's epochs with SURF's loss (`reward.model.Learner`)."""

    def __init__(self, settings: SurfSettings, generator: torch.Generator):
        self.settings, self.generator = settings, generator
        self.unlabelled_per_question = settings.unlabelled_ratio
        self.unlabelled: torch.Tensor | None = None  # (2U, H, D) on the model's device
        self.truth: torch.Tensor | None = None  # (U,): whether the first is truly better
        self._counts: torch.Tensor | None = None  # drawn, used, used and wrong (this fit)

    def use_unlabelled(self, segments: np.ndarray, true_returns: np.ndarray) -> None:
        self.unlabelled = torch.as_tensor(segments)
        self.truth = torch.as_tensor(true_returns[0::2] > true_returns[1::2])

    def start_fit(self) -> None:
        self._counts = None

    def loss(
        self,
        model: RewardModel,
        segments: torch.Tensor,
        first: torch.Tensor,
        second: torch.Tensor,
        y: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Bradley-Terry on cropped pairs, plus the weighted loss of the confident
        pseudo-labels (the mean over the whole unlabelled batch, as in their code)."""
        logits = self._cropped_logits(model, segments[first], segments[second])
        loss = F.binary_cross_entropy_with_logits(logits, y, reduction="none").mean(1)
        if self.unlabelled is not None and len(self.unlabelled) >= 2:
            loss = loss + self.settings.loss_weight * self._unlabelled_loss(model, first.shape)
        return loss.sum(), logits  # (the stopping rule's accuracy on the crops, as theirs)

    def _unlabelled_loss(self, model: RewardModel, shape: torch.Size) -> torch.Tensor:
        """The mean over the whole unlabelled batch of the confident pairs' losses. Only the
        confident pairs (often a tenth to a third) go through the network with gradients:
        the others would add exact zeros at three times the cost of labelling them."""
        assert self.unlabelled is not None and self.truth is not None
        members, batch = shape
        count = batch * self.settings.unlabelled_batch
        pick = torch.randint(0, len(self.truth), (members, count), generator=self.generator)
        device = model.device
        if self.unlabelled.device != device:  # once per fit
            self.unlabelled, self.truth = self.unlabelled.to(device), self.truth.to(device)
        pick = pick.to(device)
        a, b = self.unlabelled[2 * pick], self.unlabelled[2 * pick + 1]
        with torch.no_grad():  # pseudo-labels from the whole segments, as the teacher sees
            margin = model.step_rewards(a).sum(-1) - model.step_rewards(b).sum(-1)
            labels, used = pseudo_labels(margin, self.settings.threshold)
            wrong = used & ((labels > 0.5) != self.truth[pick])
            drawn = torch.tensor(float(used.numel()), dtype=torch.float64, device=device)
            self._count(torch.stack([drawn, used.sum().double(), wrong.sum().double()]))
        mask_a, mask_b = self._masks(pick.shape, a.shape[2], device)
        kept = int(used.sum(1).max())
        if kept == 0:
            return torch.zeros(members, device=device)
        # each member's confident pairs first (padded to the most any member has)
        slots = torch.argsort((~used).to(torch.int8), dim=1, stable=True)[:, :kept]
        real = used.gather(1, slots)

        def take(values: torch.Tensor) -> torch.Tensor:
            index = slots.reshape(*slots.shape, *(1,) * (values.dim() - 2))
            return values.gather(1, index.expand(-1, -1, *values.shape[2:]))

        logits = (model.step_rewards(take(a)) * take(mask_a)).sum(-1) - (
            model.step_rewards(take(b)) * take(mask_b)
        ).sum(-1)
        per_pair = F.binary_cross_entropy_with_logits(logits, take(labels), reduction="none")
        return (per_pair * real).sum(1) / count

    def _cropped_logits(self, model: RewardModel, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        mask_a, mask_b = self._masks(a.shape[:2], a.shape[2], model.device)
        return (model.step_rewards(a) * mask_a).sum(-1) - (model.step_rewards(b) * mask_b).sum(-1)

    def _masks(
        self, shape: tuple[int, ...], horizon: int, device: torch.device
    ) -> tuple[torch.Tensor, torch.Tensor]:
        a, b = crop_masks(tuple(shape), horizon, self.settings.crop, self.generator)
        return a.to(device), b.to(device)

    def _count(self, counts: torch.Tensor) -> None:
        self._counts = counts if self._counts is None else self._counts + counts

    def fit_metrics(self) -> dict[str, float]:
        """What the last fit did with the unlabelled pairs (read once, after the fit)."""
        drawn, used, wrong = (0, 0, 0) if self._counts is None else self._counts.tolist()
        return {
            "surf_unlabelled_pairs": 0 if self.truth is None else len(self.truth),
            "surf_pseudo_labels": used,  # confident draws that entered the loss
            "surf_pseudo_label_fraction": used / drawn if drawn else 0.0,
            "surf_pseudo_label_wrong": wrong / used if used else 0.0,
        }

    def state_dict(self) -> dict[str, Any]:
        return {}  # the unlabelled pairs are drawn again from the run seed and session

    def load_state_dict(self, state: dict[str, Any]) -> None:
        return None
