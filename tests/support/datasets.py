"""Tiny Minari datasets written without playing: one seqrank made (with provenance and
physics states) and one a foreign tool wrote (no provenance, no environment spec)."""

from __future__ import annotations

from pathlib import Path

import gymnasium
import numpy as np

from seqrank.offline.minari_write import PlayedEpisode, save_episodes

CARTPOLE = "dmc:cartpole_swingup"  # observations 5, actions 1, physics states 5


def write_datasets(folder: Path, episodes: int = 2, steps: int = 30) -> dict[str, str]:
    """`dataset`: `episodes` episodes of `steps` steps of cartpole, as `seqrank dataset
    make` writes them; `dataset_foreign`: the same sizes, written by Minari alone."""
    rng = np.random.default_rng(0)
    played = [
        PlayedEpisode(
            rng.normal(size=(steps + 1, 5)).astype(np.float32),
            rng.uniform(-1, 1, (steps, 1)).astype(np.float32),
            rng.normal(size=steps),
            np.zeros(steps, bool),
            np.arange(steps) == steps - 1,
            np.zeros(steps + 1, bool),
            k,
            np.zeros((steps + 1, 5)),
        )
        for k in range(episodes)
    ]
    made = save_episodes(played, folder / "made", CARTPOLE, {"task": CARTPOLE}, "test")
    return {"dataset": str(made.folder), "dataset_foreign": str(_foreign(folder / "foreign"))}


def _foreign(folder: Path) -> Path:
    from minari.data_collector.episode_buffer import EpisodeBuffer
    from minari.dataset.minari_storage import MinariStorage

    folder.mkdir(parents=True)
    storage = MinariStorage.new(
        folder / "data",
        observation_space=gymnasium.spaces.Box(-np.inf, np.inf, (5,), np.float32),
        action_space=gymnasium.spaces.Box(-1.0, 1.0, (1,), np.float32),
    )
    storage.update_metadata({"dataset_id": "foreign-v0", "minari_version": "0.5.4"})
    rng = np.random.default_rng(1)
    storage.update_episodes(
        [
            EpisodeBuffer(
                observations=rng.normal(size=(11, 5)).astype(np.float32),
                actions=rng.uniform(-1, 1, (10, 1)).astype(np.float32),
                rewards=list(rng.normal(size=10)),
                terminations=[False] * 10,
                truncations=[False] * 9 + [True],
            )
        ]
    )
    return folder
