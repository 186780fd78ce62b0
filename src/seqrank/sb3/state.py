"""Everything a `PreferenceFeedback` holds between SB3's calls, in one object: what
`saving` writes, and what a loaded feedback restores into a new one."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.config import TrainConfig
from seqrank.sb3.build import Task
from seqrank.sb3.envs import PreferenceVecEnv, SeededEpisodes
from seqrank.sb3.run import FeedbackRun
from seqrank.sb3.tables import EpisodeTable, ReplayTable


@dataclass
class Resumed:
    """What a loaded feedback restores when it trains again."""

    folder: Path
    global_rng: dict[str, Any]  # the random streams SB3 draws from (`streams`)
    true: np.ndarray | None  # the true rewards beside the replay buffer
    steps_into_episodes: list[int]  # each environment's, when saved (0: at an episode end)


@dataclass
class FeedbackState:
    """The feedback's settings, parts and progress.

    `given` is the config as resolved from the keywords (saved); `config` the one in
    effect, without the pre-training phase for an agent that does not pre-train (known at
    the start of training, with `pretraining` and `critic_reset`)."""

    given: TrainConfig
    options: dict[str, Any]  # the callback's own keywords: pretrain, reset_critic, n_envs, ...
    from_task_name: bool
    task: Task
    run: FeedbackRun
    env: PreferenceVecEnv
    seeded: list[SeededEpisodes]  # the task's environments, whose episodes are seeded
    page: Any = None  # the labelling page, for teacher="human"
    config: TrainConfig = field(init=False)
    table: ReplayTable | EpisodeTable | None = None  # where relabelling writes
    pretraining: bool = False
    critic_reset: bool = False
    metrics: list[dict[str, Any]] = field(default_factory=list)  # a row per session
    resumed: Resumed | None = None

    def __post_init__(self) -> None:
        self.config = self.given
