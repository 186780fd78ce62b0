"""A dataset made from its sources (`seqrank dataset make`) and a dataset described
(`seqrank dataset info`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.envs.scoring import Metric, task_metric
from seqrank.offline.minari_io import (
    Location,
    episode_successes,
    load_dataset,
    read_metadata,
    task_label,
)
from seqrank.offline.minari_write import PlayedEpisode, check_new, save_episodes
from seqrank.offline.sources import (
    Source,
    check_source,
    episode_counts,
    random_play,
    run_episodes,
    scripted_play,
)

FORMAT = "seqrank-dataset-1"  # what our provenance entry holds, should it change


@dataclass(frozen=True)
class MakeRequest:
    task: str
    sources: list[Source]
    episodes: int | None  # None: every episode of a run, the only source
    noise: float  # scripted sources' action noise (SD) unless their own is given
    seed: int
    command: str  # how it was asked for, for the provenance


def check_request(request: MakeRequest) -> list[int | None]:
    """Each source's episode count, or a ValueError, before anything is played."""
    task_label(request.task)  # an unknown task is named before anything else
    _check_task(request.task)
    if not np.isfinite(request.noise) or request.noise < 0:
        raise ValueError(f"--noise must be a number >= 0, got {request.noise}")
    counts: list[int | None]
    if request.episodes is None:
        if len(request.sources) != 1 or request.sources[0].kind != "run":
            raise ValueError(
                "--episodes is needed: only a run, as the one source, gives all its episodes"
            )
        counts = [None]
    elif request.episodes < 1:
        raise ValueError(f"--episodes must be at least 1, got {request.episodes}")
    else:
        counts = list(episode_counts(request.sources, request.episodes))
    for source, count in zip(request.sources, counts, strict=True):
        check_source(source, request.task, count)
    return counts


def check_out(out: str | Path) -> Location:
    """Where the new dataset goes: a ValueError for an empty name or one that exists."""
    if not str(out).strip():
        raise ValueError(
            "--out is empty; accepted: a Minari dataset id, (namespace/)name-vN, or the "
            "path of a dataset folder that does not exist yet"
        )
    return check_new(out)


def _check_task(task: str) -> None:
    """A ValueError (SettingError) for a task whose environment seqrank cannot play, e.g.
    a Gymnasium task with Discrete actions: built once, so before anything is played."""
    from seqrank.envs import make_env

    make_env(task).close()


def make_dataset(request: MakeRequest, out: str | Path) -> Location:
    """Play (or take) each source's episodes and write them as a Minari dataset at `out`
    (a Minari id or a folder path that does not exist yet)."""
    task = task_label(request.task)
    check_out(out)
    counts = check_request(request)
    episodes: list[PlayedEpisode] = []
    parts = []
    for index, (source, count) in enumerate(zip(request.sources, counts, strict=True)):
        seeds = np.random.SeedSequence([request.seed, index])
        if source.kind == "run":
            made = run_episodes(source, task, count)
        elif source.kind == "scripted":
            noise = source.noise if source.noise is not None else request.noise
            made = scripted_play(task, int(count or 0), noise, seeds)
        else:
            made = random_play(task, int(count or 0), seeds)
        parts.append(_part(source, request, index, len(episodes), made))
        episodes.extend(made)
    provenance = _provenance(request, task, parts, episodes)
    description = f"{task}: " + ", ".join(
        f"{part['episodes']} episodes of {part['source']}" for part in parts
    )
    return save_episodes(episodes, out, task, provenance, description)


def _part(
    source: Source, request: MakeRequest, index: int, first: int, made: list[PlayedEpisode]
) -> dict[str, Any]:
    part: dict[str, Any] = {
        "source": source.kind,
        "episodes": len(made),
        "first_episode": first,
        "transitions": int(sum(len(e.rewards) for e in made)),
    }
    if source.kind == "run":
        part["run"] = str(source.run)
        part["final_observation"] = "repeated"  # a run keeps none after the last action
    else:
        part["seed"] = [request.seed, index]  # numpy SeedSequence entropy of its streams
    if source.kind == "scripted":
        part["noise"] = source.noise if source.noise is not None else request.noise
        part["policy"] = "metaworld.policies"
    if source.share is not None:
        part["share"] = source.share
    return part


def _provenance(
    request: MakeRequest, task: str, parts: list[dict[str, Any]], episodes: list[PlayedEpisode]
) -> dict[str, Any]:
    from seqrank import __version__

    return {
        "format": FORMAT,
        "task": task,
        "sources": parts,
        "seed": request.seed,
        "episodes": len(episodes),
        "transitions": int(sum(len(e.rewards) for e in episodes)),
        "seqrank_version": __version__,
        "command": request.command,
        "algorithm": "seqrank dataset make: " + "+".join(p["source"] for p in parts),
    }


def describe(name_or_path: str | Path, task: str | None = None) -> dict[str, Any]:
    """What `dataset info` shows: sizes, returns, success rate where recorded, provenance
    (`task`: of a dataset that does not name one, as `load_dataset` takes it)."""
    location, metadata = read_metadata(name_or_path)
    dataset = load_dataset(name_or_path, task)
    returns = dataset.episode_returns()
    lengths = np.diff(np.append(dataset.starts, len(dataset)))
    successes = episode_successes(name_or_path)
    rate = None if successes is None else float(successes.mean())
    if rate is not None and task_metric(dataset.task, [100 * rate]) is not Metric.SUCCESS:
        rate = None  # a task with no success signal (DMControl) records False throughout
    return {
        "dataset": metadata.get("dataset_id"),
        "path": str(location.folder),
        "task": dataset.task,
        "episodes": dataset.episode_count,
        "transitions": len(dataset),
        "episode_length": {"min": int(lengths.min()), "max": int(lengths.max())},
        "obs_dim": dataset.obs_dim,
        "act_dim": dataset.act_dim,
        "return": {
            "mean": float(returns.mean()),
            "std": float(returns.std()),
            "min": float(returns.min()),
            "max": float(returns.max()),
        },
        "success_rate": rate,
        "provenance": metadata.get("seqrank"),
        "minari_version": metadata.get("minari_version"),
    }
