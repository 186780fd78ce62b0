"""The run's counters: what a checkpoint restores besides the parts' own state."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np


@dataclass
class Counters:
    step: int = 0
    episode: int = 0
    sessions: int = 0
    asked: int = 0
    answered: int = 0
    inferred: int = 0
    inferred_wrong: int = 0
    last_session_step: int = 0
    last_checkpoint_step: int = 0
    evaluations: int = 0
    last_eval_return: float | None = None
    last_eval_success: float | None = None
    train_seconds: float = 0.0
    extra: dict[str, float] = field(default_factory=dict)  # e.g. MRN's outer loss

    def state_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @property
    def steps_per_second(self) -> float:
        return self.step / max(self.train_seconds, 1e-9)


def episode_seed(run_seed: int, *path: int) -> int:
    """The seed of one episode: training episodes are (0, k), evaluations (1, k, i)."""
    return int(np.random.SeedSequence([run_seed, *path]).generate_state(1)[0])
