"""Reward ensemble and its Bradley-Terry training (SPEC section 5).

The members' weights are stacked, so the whole ensemble is one batched matmul per layer,
and each member can see its own minibatch. Labels are soft targets (1, 0 or 0.5 for
equal), so hard, soft and equal labels share one loss path.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

LEAKY_SLOPE = 0.01  # torch's default negative slope


class EnsembleMLP(nn.Module):
    """`members` independent MLPs: LeakyReLU hidden layers, tanh scalar output."""

    def __init__(self, members: int, inputs: int, hidden: int, layers: int):
        super().__init__()
        sizes = [inputs] + [hidden] * layers + [1]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for a, b in itertools.pairwise(sizes):
            bound = 1 / math.sqrt(a)  # the default nn.Linear initialisation, per member
            self.weights.append(nn.Parameter(torch.empty(members, a, b).uniform_(-bound, bound)))
            self.biases.append(nn.Parameter(torch.empty(members, 1, b).uniform_(-bound, bound)))
        # the same parameters as a plain tuple: a ParameterList's indexing costs microseconds
        self._layers = tuple(zip(self.weights, self.biases, strict=True))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """x: (members, N, inputs) or (N, inputs) shared by all; returns (members, N, 1)."""
        if x.dim() == 2:
            x = x.unsqueeze(0).expand(len(self.weights[0]), -1, -1)
        last = len(self.weights) - 1
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            x = torch.baddbmm(b, x, w)
            x = torch.tanh(x) if i == last else F.leaky_relu(x, LEAKY_SLOPE)
        return x

    def one_row_numpy(self, features: np.ndarray) -> float:
        """The members' mean output for one row of features, in numpy on the host (fp32
        weights read through views of the current parameters: nothing goes stale)."""
        x = features[None, None]
        last = len(self._layers) - 1
        for i, (w, b) in enumerate(self._layers):
            x = np.matmul(x, w.detach().numpy()) + b.detach().numpy()
            x = np.tanh(x) if i == last else np.maximum(x, LEAKY_SLOPE * x)
        return float(x.mean())


@dataclass(frozen=True)
class RewardTrainResult:
    epochs: int
    loss: float
    accuracy: float
    learner: dict[str, float] = field(default_factory=dict)  # the learner's own measures


class Learner(Protocol):
    """How one fit uses the labelled pairs (`reward.learners`: plain, SURF, RIME).

    The fit asks it, each epoch, which pairs (and labels) to train on, and, each
    minibatch, for the loss; it keeps what it needs between fits (`state_dict`)."""

    unlabelled_per_question: int  # unlabelled pairs it wants per question asked (0: none)
    min_epochs: int  # epochs a fit runs before the accuracy may stop it

    def use_unlabelled(self, segments: np.ndarray, true_returns: np.ndarray) -> None:
        """Segments (2U, H, D) forming pairs (2i, 2i + 1), and their true returns (2U,)."""

    def start_fit(self) -> None: ...

    def epoch_pairs(self, model: RewardModel, segments: torch.Tensor, pairs: Pairs) -> Pairs: ...

    def loss(
        self,
        model: RewardModel,
        segments: torch.Tensor,
        first: torch.Tensor,
        second: torch.Tensor,
        y: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(the members' summed loss, logits (members, B)) of one minibatch."""

    def fit_metrics(self) -> dict[str, float]: ...

    def state_dict(self) -> dict[str, Any]: ...

    def load_state_dict(self, state: dict[str, Any]) -> None: ...


Pairs = tuple[torch.Tensor, torch.Tensor, torch.Tensor]  # first, second, labels


def bradley_terry(
    model: RewardModel,
    segments: torch.Tensor,
    first: torch.Tensor,
    second: torch.Tensor,
    y: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """BCE on segment-sum logits, the mean over a member's minibatch summed over members."""
    logits = model.segment_returns(segments[first]) - model.segment_returns(segments[second])
    loss = F.binary_cross_entropy_with_logits(logits, y, reduction="none").mean(1).sum()
    return loss, logits


class PlainLearner:
    """Every labelled pair, every epoch, with its label (PEBBLE)."""

    unlabelled_per_question = 0
    min_epochs = 1

    def use_unlabelled(self, segments: np.ndarray, true_returns: np.ndarray) -> None:
        return None

    def start_fit(self) -> None:
        return None

    def epoch_pairs(self, model: RewardModel, segments: torch.Tensor, pairs: Pairs) -> Pairs:
        return pairs

    def loss(
        self,
        model: RewardModel,
        segments: torch.Tensor,
        first: torch.Tensor,
        second: torch.Tensor,
        y: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        return bradley_terry(model, segments, first, second, y)

    def fit_metrics(self) -> dict[str, float]:
        return {}

    def state_dict(self) -> dict[str, Any]:
        return {}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        return None


class RewardModel:
    def __init__(
        self, members: int, inputs: int, hidden: int, layers: int, lr: float, device: torch.device
    ):
        self.device = device
        self.net = EnsembleMLP(members, inputs, hidden, layers).to(device)
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=lr)

    @property
    def members(self) -> int:
        return len(self.net.weights[0])

    def reward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """The agent's reward: the ensemble mean, shape (N, 1)."""
        if len(obs) == 1 and self.device.type == "cpu" and not torch.is_grad_enabled():
            # a step's reward as the loop stores it: in numpy, where torch's cost per call
            # is most of the time at one row
            features = torch.cat([obs[0], action[0]]).numpy()
            return torch.tensor([[self.net.one_row_numpy(features)]])
        return self.net(torch.cat([obs, action], dim=-1)).mean(0)

    def step_rewards(self, segments: torch.Tensor) -> torch.Tensor:
        """segments: (N, H, D) shared, or (members, N, H, D); returns (members, N, H)."""
        n, horizon, features = segments.shape[-3:]
        flat = segments.reshape(*segments.shape[:-3], n * horizon, features)
        return self.net(flat).reshape(self.members, n, horizon)

    def segment_returns(self, segments: torch.Tensor) -> torch.Tensor:
        """segments: (N, H, D) shared, or (members, N, H, D); returns (members, N)."""
        return self.step_rewards(segments).sum(-1)

    @torch.no_grad()
    def member_returns(self, segments: np.ndarray, chunk: int = 1024) -> np.ndarray:
        """Per-member predicted returns (members, N) of segment features (N, H, D)."""
        parts = []
        for start in range(0, len(segments), chunk):
            batch = torch.as_tensor(segments[start : start + chunk], device=self.device)
            parts.append(self.segment_returns(batch).cpu().numpy())
        return np.concatenate(parts, axis=1)

    def train(
        self,
        segments: torch.Tensor,
        first: torch.Tensor,
        second: torch.Tensor,
        labels: torch.Tensor,
        max_epochs: int,
        minibatch: int,
        stop_accuracy: float,
        generator: torch.Generator,
        sync_every_step: bool = True,
        learner: Learner | None = None,
        stop_pairs: torch.Tensor | None = None,
    ) -> RewardTrainResult:
        """Bradley-Terry on segment sums; each member its own shuffle of the epoch's pairs.

        labels: probability that `first` is preferred. Stops early once the mean train
        accuracy over hard labels exceeds `stop_accuracy`, but not before the learner's
        `min_epochs`. `stop_pairs` (bool, one per pair; None: every pair) limits that
        accuracy to the pairs it marks (the asked ones, say): a pair is known by its two
        segments, so the marks follow the pairs a learner chooses and reorders each epoch
        (two segments form one pair, asked or inferred, never both). `sync_every_step`
        reads the loss back after every minibatch, as the reference code does; otherwise
        the sums stay on the device and are read once per epoch, for the stopping rule.
        `learner` (plain by default) chooses each epoch's pairs and each minibatch's loss.
        """
        learner = learner if learner is not None else PlainLearner()
        learner.start_fit()
        counted = None if stop_pairs is None else _pair_keys(first, second, len(segments))
        if counted is not None and stop_pairs is not None:
            counted = counted[stop_pairs.to(counted.device)]
        loss_value, accuracy, epochs = 0.0, 0.0, 0
        for epochs in range(1, max_epochs + 1):
            pairs = learner.epoch_pairs(self, segments, (first, second, labels))
            loss_sum, correct, total, steps = self._epoch(
                learner, segments, pairs, minibatch, generator, sync_every_step, counted
            )
            loss_value = float(loss_sum) / max(steps, 1)  # (a learner may keep no pair)
            accuracy = float(correct / total) if total else 1.0
            if accuracy > stop_accuracy and epochs >= learner.min_epochs:
                break
        return RewardTrainResult(epochs, loss_value, accuracy, learner.fit_metrics())

    def _epoch(
        self,
        learner: Learner,
        segments: torch.Tensor,
        pairs: Pairs,
        minibatch: int,
        generator: torch.Generator,
        sync_every_step: bool,
        counted: torch.Tensor | None,
    ) -> tuple[float, float, float, int]:
        """One pass over the epoch's pairs in minibatches: (summed loss, hits, hard labels
        counted, steps). `counted`: the keys (`_pair_keys`) of the pairs the hits count."""
        first_e, second_e, labels_e = pairs
        size = len(labels_e)
        order = torch.stack(
            [torch.randperm(size, generator=generator) for _ in range(self.members)]
        ).to(self.device)
        mask = None
        if counted is not None:
            mask = torch.isin(_pair_keys(first_e, second_e, len(segments)), counted)
        totals = torch.zeros(3, dtype=torch.float64, device=self.device)
        host_totals, steps = np.zeros(3), 0
        for start in range(0, size, minibatch):
            idx = order[:, start : start + minibatch]  # (members, B)
            step_totals = self._step(
                learner, segments, first_e[idx], second_e[idx], labels_e[idx],
                None if mask is None else mask[idx],
            )  # fmt: skip
            if sync_every_step:
                host_totals += step_totals.cpu().numpy()
            else:
                totals += step_totals
            steps += 1
        if not sync_every_step:
            host_totals = totals.cpu().numpy()
        loss_sum, correct, total = host_totals
        return loss_sum, correct, total, steps

    def _step(
        self,
        learner: Learner,
        segments: torch.Tensor,
        first: torch.Tensor,
        second: torch.Tensor,
        y: torch.Tensor,
        counted: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """One optimiser step; returns (mean member loss, hits, hard labels) on the device,
        the hits and labels of the `counted` pairs only when given."""
        loss, logits = learner.loss(self, segments, first, second, y)
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        self.optimizer.step()
        with torch.no_grad():
            hard = y != 0.5
            if counted is not None:
                hard = hard & counted
            hits = ((logits > 0) == (y > 0.5)) & hard
            parts = (loss.detach() / self.members, hits.sum(), hard.sum())
            return torch.stack([p.double() for p in parts])

    def state_dict(self) -> dict[str, Any]:
        return {"net": self.net.state_dict(), "optimizer": self.optimizer.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.net.load_state_dict(state["net"])
        self.optimizer.load_state_dict(state["optimizer"])


def _pair_keys(first: torch.Tensor, second: torch.Tensor, segments: int) -> torch.Tensor:
    """One number per pair of segment indices, the same whichever comes first."""
    return torch.minimum(first, second) * segments + torch.maximum(first, second)
