"""Played episodes written as a new Minari dataset (HDF5), with seqrank's provenance.

Each episode's infos hold, one row per observation (T + 1, as Minari's own collector
writes them: the reset's, then each step's): `success` (the task's signal, where the
source has one), `state` (the full physics state, from which the labelling page renders
a segment's clip) and `task_index` (Meta-World's task, to render it in the right scene).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.offline.minari_io import DATA_FORMAT, PROVENANCE_KEY, Location, locate


@dataclass(frozen=True)
class PlayedEpisode:
    """One episode as played: `observations` has one row more than `actions` (the last
    observation, after the last action), as Minari stores episodes; so do the infos."""

    observations: np.ndarray  # (T + 1, obs_dim) float32
    actions: np.ndarray  # (T, act_dim) float32
    rewards: np.ndarray  # (T,)
    terminations: np.ndarray  # (T,) bool
    truncations: np.ndarray  # (T,) bool
    success: np.ndarray | None  # (T + 1,) bool: the task's success signal, where recorded
    seed: int | None  # the reset seed, where the episode is a function of one
    states: np.ndarray | None = None  # (T + 1, state_dim) physics states, where recorded
    context: int | None = None  # Meta-World's task index (the scene to render in)

    def infos(self) -> dict[str, np.ndarray] | None:
        rows = len(self.observations)
        infos: dict[str, np.ndarray] = {}
        if self.success is not None:
            infos["success"] = self.success.astype(bool)
        if self.states is not None:
            infos["state"] = self.states.astype(np.float64)
        if self.context is not None:
            infos["task_index"] = np.full(rows, self.context, np.int64)
        return infos or None


def save_episodes(
    episodes: list[PlayedEpisode],
    name_or_path: str | Path,
    task: str,
    provenance: dict[str, Any],
    description: str,
) -> Location:
    """Write played episodes of `task` as a new Minari dataset; its folder must not
    exist, and nothing is left behind when writing fails."""
    from minari import __version__ as minari_version

    from seqrank.dirs import missing_folders, remove_made

    location = check_new(name_or_path)
    obs_dim, act_dim = episodes[0].observations.shape[1], episodes[0].actions.shape[1]
    made = missing_folders(location.folder)
    # Written beside its place and renamed into it: a process killed mid-write (kill -9)
    # leaves a hidden staging folder, never a folder that looks like a finished dataset.
    staging = Location(
        location.folder.with_name(f".{location.folder.name}.part-{os.getpid()}"),
        location.dataset_id,
    )
    try:
        staging.folder.mkdir(parents=True)
        storage = _new_storage(staging, task, obs_dim, act_dim)
        storage.update_metadata(
            {
                "dataset_id": location.dataset_id,
                "minari_version": minari_version,
                "algorithm_name": provenance.get("algorithm", "seqrank dataset make"),
                "description": description,
                PROVENANCE_KEY: provenance,
            }
        )
        storage.update_episodes(_buffers(episodes))
        os.rename(staging.folder, location.folder)
    except BaseException:
        shutil.rmtree(staging.folder, ignore_errors=True)
        remove_made(made)  # the parents made for it, where still empty
        raise
    return location


def check_new(name_or_path: str | Path) -> Location:
    """Where a new dataset goes; a ValueError when something is already there."""
    from seqrank.dirs import check_folder

    location = locate(name_or_path)
    if location.folder.exists():
        raise ValueError(
            f"dataset {name_or_path} already exists ({location.folder}); choose another name "
            "or remove it"
        )
    check_folder(location.folder, "dataset")
    return location


def _new_storage(location: Location, task: str, obs_dim: int, act_dim: int) -> Any:
    import gymnasium
    from minari.dataset.minari_storage import MinariStorage

    observation_space = gymnasium.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32)
    action_space = gymnasium.spaces.Box(-1.0, 1.0, (act_dim,), np.float32)
    return MinariStorage.new(
        location.data,
        observation_space=observation_space,
        action_space=action_space,
        env_spec=_env_spec(task),
        data_format=DATA_FORMAT,
        jpeg_encoding=False,
    )


def _env_spec(task: str) -> Any:
    """The Gymnasium spec seqrank registers for the task (`seqrank/<task>`), so Minari's
    `recover_environment` gives it back; None for a user's own factory."""
    import gymnasium

    import seqrank  # noqa: F401  (registers seqrank's ids)
    from seqrank.registration import gymnasium_ids

    ids = {name: env_id for env_id, name in gymnasium_ids().items()}
    if task in ids:
        return gymnasium.spec(ids[task])
    if task.startswith("gym:"):
        return gymnasium.spec(task.removeprefix("gym:"))
    return None


def _buffers(episodes: list[PlayedEpisode]) -> Iterator[Any]:
    from minari.data_collector.episode_buffer import EpisodeBuffer

    for index, episode in enumerate(episodes):
        yield EpisodeBuffer(
            id=index,
            seed=episode.seed,
            observations=episode.observations.astype(np.float32),
            actions=episode.actions.astype(np.float32),
            rewards=list(np.asarray(episode.rewards, np.float64)),
            terminations=list(episode.terminations.astype(bool)),
            truncations=list(episode.truncations.astype(bool)),
            infos=episode.infos(),
        )
