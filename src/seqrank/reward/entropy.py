"""Unsupervised pre-training reward: state entropy by k-nearest-neighbour distance (SPEC 6)."""

from __future__ import annotations

from typing import Any

import torch


class RunningMeanStd:
    """Mean and variance over every value seen, merged batch by batch (Chan et al.).

    The merge of two partial results (n_a, mean_a, M2_a) and (n_b, mean_b, M2_b) is
    M2 = M2_a + M2_b + delta^2 n_a n_b / (n_a + n_b), delta = mean_b - mean_a.
    """

    def __init__(self) -> None:
        self.count, self.mean, self.var = 0, 0.0, 1.0

    def update(self, values: torch.Tensor) -> None:
        n_b = values.numel()
        if n_b == 0:
            return
        mean_b = float(values.mean())
        var_b = float(values.var(unbiased=False)) if n_b > 1 else 0.0
        n_a, total = self.count, self.count + n_b
        delta = mean_b - self.mean
        m2 = self.var * n_a + var_b * n_b + delta * delta * n_a * n_b / total
        self.mean += delta * n_b / total
        self.var, self.count = m2 / total, total

    @property
    def std(self) -> float:
        return max(self.var, 0.0) ** 0.5

    def state_dict(self) -> dict[str, Any]:
        return {"count": self.count, "mean": self.mean, "var": self.var}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.count, self.mean, self.var = state["count"], state["mean"], state["var"]


def knn_distance(
    queries: torch.Tensor, stored: torch.Tensor, k: int, chunk: int = 16384
) -> torch.Tensor:
    """Distance from each query to its k-th nearest stored state, (B, 1).

    The queries are themselves stored, so the nearest (distance 0) is skipped. Distances
    are computed in chunks of stored states so memory stays bounded.
    """
    best: torch.Tensor | None = None
    for start in range(0, len(stored), chunk):
        dists = torch.cdist(queries, stored[start : start + chunk])
        merged = dists if best is None else torch.cat([best, dists], dim=1)
        best = merged.topk(min(k + 1, merged.shape[1]), dim=1, largest=False).values
    assert best is not None
    return best[:, -1:]


def intrinsic_reward(
    queries: torch.Tensor, stored: torch.Tensor, k: int, stats: RunningMeanStd
) -> torch.Tensor:
    """k-NN distance divided by its running standard deviation."""
    distance = knn_distance(queries, stored, k)
    stats.update(distance)
    return distance / max(stats.std, 1e-8)
