"""Minari datasets on disk: where a name or path points, reading one into an
`OfflineDataset`, and writing played episodes as one.

A dataset is named either by a Minari dataset id, `(namespace/)name-vN` (e.g.
`seqrank/door-open-scripted-v0`), found in Minari's local datasets folder
(`$MINARI_DATASETS_PATH`, else `~/.minari/datasets`), or by a path to a dataset's folder
(the one holding `data/`, or `data/` itself); a path that begins with `/`, `.` or `~`, or
that is not an id, is a path. Nothing is ever downloaded.

seqrank writes HDF5 (Minari's default format; `h5py`). Its provenance (task, sources,
seeds, sizes, seqrank version, command) is the `seqrank` entry of Minari's
`metadata.json`; per-step `success` goes in the episodes' infos. A foreign dataset's task
comes from its environment spec where that names a seqrank task (`seqrank/<task>` or a
Gymnasium id seqrank plays as `gym:ID`), or from `task=` where the caller names it. A
dataset holding a NaN or infinity in its observations, actions or rewards is refused at
load (it would make every return, pool and update NaN).

seqrank's policies act in [-1, 1] and its environments scale actions to the task's
bounds, so a dataset's actions are read in [-1, 1]: seqrank writes its datasets with
that action space (Box(-1, 1)), and a foreign dataset whose Box action space has other
finite bounds (Pendulum's [-2, 2]) has its actions rescaled linearly, per dimension, on
load (`meta["actions_rescaled_from"]` keeps the bounds); infinite bounds are refused.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.episodes import Episode
from seqrank.offline.dataset import OfflineDataset

DATA_FORMAT = "hdf5"
PROVENANCE_KEY = "seqrank"  # our entry in Minari's metadata.json
# Minari's id syntax (minari.dataset.minari_dataset.DATASET_ID_RE, with the version required)
_DATASET_ID = re.compile(r"^(?:[-_\w][-_\w/]*[-_\w]+/)?[-_.\w]+-v\d+$")


@dataclass(frozen=True)
class Location:
    """Where a dataset lives: its folder and the Minari `data/` folder inside it."""

    folder: Path
    dataset_id: str  # the id it is (or is to be) known by in its metadata

    @property
    def data(self) -> Path:
        return self.folder / "data"


def datasets_root() -> Path:
    """Minari's local datasets folder (read from the environment as Minari does, but
    without creating it: looking a name up leaves nothing behind)."""
    root = os.environ.get("MINARI_DATASETS_PATH")
    return Path(root) if root else Path.home() / ".minari" / "datasets"


def is_dataset_id(text: str) -> bool:
    return not text.startswith(("/", ".", "~")) and bool(_DATASET_ID.match(text))


def locate(name_or_path: str | Path) -> Location:
    """The dataset a name or path points at (which may not exist yet)."""
    text = str(name_or_path)
    if isinstance(name_or_path, str) and is_dataset_id(text):
        return Location(datasets_root() / text, text)
    folder = Path(text).expanduser().absolute()  # Minari's HDF5 storage mangles relative paths
    if folder.name == "data" and (folder / "metadata.json").is_file():
        folder = folder.parent  # the data folder itself was named
    return Location(folder, _id_for_path(folder))


def _id_for_path(folder: Path) -> str:
    """A valid Minari id for a dataset written at a path (Minari requires one)."""
    stem = re.sub(r"[^-_.\w]", "-", folder.name) or "dataset"
    return stem if _DATASET_ID.match(stem) else f"{stem}-v0"


def _missing(name_or_path: str | Path) -> str:
    return (
        f"no Minari dataset at {name_or_path!r}: give a dataset id from {datasets_root()} "
        "(e.g. seqrank/door-open-scripted-v0) or the path of a dataset folder; make one with "
        "`seqrank dataset make`"
    )


def read_metadata(name_or_path: str | Path) -> tuple[Location, dict[str, Any]]:
    """A dataset's location and its raw Minari metadata; a ValueError when there is none."""
    import json

    location = locate(name_or_path)
    file = location.data / "metadata.json"
    if not file.is_file():
        raise ValueError(_missing(name_or_path))
    try:
        metadata = json.loads(file.read_text())
    except (OSError, ValueError) as problem:
        raise ValueError(f"dataset {name_or_path}: unreadable metadata.json ({problem})") from None
    return location, metadata


def dataset_task(metadata: dict[str, Any]) -> str | None:
    """The seqrank task a dataset's metadata names: seqrank's provenance, else its
    environment spec's id where seqrank plays it; None when neither says."""
    provenance = metadata.get(PROVENANCE_KEY)
    if isinstance(provenance, dict) and provenance.get("task"):
        return str(provenance["task"])
    return _task_of_env_spec(metadata.get("env_spec"))


def _task_of_env_spec(spec_json: object) -> str | None:
    import json

    if not isinstance(spec_json, str):
        return None
    try:
        env_id = str(json.loads(spec_json)["id"])
    except (ValueError, KeyError, TypeError):
        return None
    from seqrank.registration import gymnasium_ids

    if env_id in gymnasium_ids():
        return gymnasium_ids()[env_id]
    import gymnasium

    return f"gym:{env_id}" if env_id in gymnasium.registry else None


def same_task(first: str, second: str) -> bool:
    """Whether two task names name one task (`door-open` and `metaworld:door-open-v3`)."""
    from seqrank.envs import canonical_task

    return canonical_task(first) == canonical_task(second)


def task_label(task: str) -> str:
    """A task's full name, suite first (`dmc:cartpole_swingup`), as datasets record it."""
    from seqrank.envs import canonical_task

    suite, name = canonical_task(task)
    return name if suite == "custom" else f"{suite}:{name}"


def load_dataset(path_or_name: str | Path, task: str | None = None) -> OfflineDataset:
    """A Minari dataset (an id in Minari's local folder, or a dataset folder's path) as an
    `OfflineDataset` of `task`.

    The task is the one seqrank recorded when it made the dataset, else the one its
    environment spec names; `task` names it for a foreign dataset that names none, and
    when given must agree with what the dataset says. The dataset's observation and
    action sizes are checked against the task's environment whenever it is named here or
    not recorded by seqrank. Every problem is a ValueError naming the dataset and what is
    accepted.
    """
    location, metadata = read_metadata(path_or_name)
    recorded = dataset_task(metadata)
    if recorded is None and task is None:
        env_id = _env_id(metadata)
        spec = (
            "records no environment (no environment spec)"
            if env_id is None
            else f"its environment spec {env_id!r} is not a task seqrank plays"
        )
        raise ValueError(
            f"dataset {path_or_name} does not name a seqrank task (no seqrank provenance, and "
            f"{spec}): name the task its episodes were played on (--task, or task= in Python)"
        )
    if recorded is not None and task is not None and not same_task(recorded, task):
        raise ValueError(
            f"dataset {path_or_name} is of task {recorded}, not {task}: give a dataset of "
            f"{task} or leave the task out to use {recorded}"
        )
    name = task_label(task if task is not None else str(recorded))
    provenance = metadata.get(PROVENANCE_KEY)
    dataset = _read_episodes(location, name, metadata, path_or_name)
    if task is not None or not isinstance(provenance, dict):
        check_sizes(dataset, path_or_name)
    return dataset


def _env_id(metadata: dict[str, Any]) -> str | None:
    import json

    try:
        return str(json.loads(str(metadata["env_spec"]))["id"])
    except (KeyError, ValueError, TypeError):
        return None


def check_sizes(dataset: OfflineDataset, name: str | Path) -> None:
    """A ValueError unless the dataset's observations and actions have the task's sizes."""
    from seqrank.envs import make_env

    env = make_env(dataset.task)
    try:
        expected, found = (env.obs_dim, env.act_dim), (dataset.obs_dim, dataset.act_dim)
    finally:
        env.close()
    if expected != found:
        raise ValueError(
            f"dataset {name} has observations of size {found[0]} and actions of size "
            f"{found[1]}; task {dataset.task} has {expected[0]} and {expected[1]}: give a "
            "dataset made on this task"
        )


def _read_episodes(
    location: Location, task: str, metadata: dict[str, Any], name: str | Path
) -> OfflineDataset:
    columns: dict[str, list[np.ndarray]] = {key: [] for key in _COLUMNS}
    bounds = _action_bounds(metadata, name)
    for index, episode in enumerate(_minari_episodes(location, name)):
        observations = _flat_rows(episode["observations"], name, "observations")
        actions = _flat_rows(episode["actions"], name, "actions")
        rewards = np.asarray(episode["rewards"], np.float32)
        _check_finite(name, episode.get("id", index), observations, actions, rewards)
        if bounds is not None:  # linear, per dimension: low -> -1, high -> 1
            low, high = bounds
            actions = (2.0 * (actions - low) / (high - low) - 1.0).astype(np.float32)
        steps = len(actions)
        if steps == 0:
            continue  # an empty episode holds no transition
        columns["observations"].append(observations[:steps])
        columns["next_observations"].append(observations[1 : steps + 1])
        columns["actions"].append(actions)
        columns["rewards"].append(rewards)
        columns["terminations"].append(np.asarray(episode["terminations"], bool))
        columns["truncations"].append(np.asarray(episode["truncations"], bool))
    if not columns["actions"]:
        raise ValueError(f"dataset {name} holds no episode with a step")
    lengths = [len(a) for a in columns["actions"]]
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    provenance = metadata.get(PROVENANCE_KEY)
    meta = dict(provenance) if isinstance(provenance, dict) else {"foreign": True}
    if bounds is not None:
        meta["actions_rescaled_from"] = {"low": bounds[0].tolist(), "high": bounds[1].tolist()}
    meta.update(dataset_id=metadata.get("dataset_id"), path=str(location.folder))
    arrays = {key: np.concatenate(rows) for key, rows in columns.items()}
    return OfflineDataset(task=task, starts=starts, meta=meta, **arrays)


def _action_bounds(metadata: dict[str, Any], name: str | Path) -> tuple[Any, Any] | None:
    """The (low, high) of a Box action space other than [-1, 1], whose actions are to be
    rescaled to seqrank's [-1, 1]; None for [-1, 1] (what seqrank writes) or a space that
    is not a Box (refused by `_flat_rows`); a ValueError for infinite or empty bounds."""
    import gymnasium
    from minari.serialization import deserialize_space

    try:
        space = deserialize_space(metadata["action_space"])
    except (KeyError, ValueError, TypeError, NotImplementedError):
        return None  # no readable space: the actions are taken as they are
    if not isinstance(space, gymnasium.spaces.Box):
        return None
    low, high = (np.asarray(b, np.float64).ravel() for b in (space.low, space.high))
    if np.all(low == -1.0) and np.all(high == 1.0):
        return None
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high)) and np.all(low < high)):
        raise ValueError(
            f"dataset {name} has actions in {space}, without finite bounds to rescale them "
            "to seqrank's [-1, 1]; accepted: Box action spaces with finite bounds"
        )
    return low, high


def _check_finite(name: str | Path, episode: object, *fields: np.ndarray) -> None:
    """A ValueError naming the episode and field holding a NaN or infinity: one would turn
    returns, pools and every update of a learner into NaN."""
    for what, values in zip(("observations", "actions", "rewards"), fields, strict=True):
        if not np.all(np.isfinite(values)):
            raise ValueError(
                f"dataset {name}: episode {episode} has a non-finite value (NaN or infinity) "
                f"in its {what}; seqrank reads datasets whose values are all finite"
            )


_COLUMNS = (
    "observations",
    "actions",
    "rewards",
    "next_observations",
    "terminations",
    "truncations",
)


def _minari_episodes(location: Location, name: str | Path) -> Iterator[dict[str, Any]]:
    """The raw episodes through Minari's own reader (any storage format it knows)."""
    from minari.dataset.minari_storage import MinariStorage

    try:
        storage = MinariStorage.read(location.data)
    except ValueError as problem:  # Minari's "No data found in data path ..."
        if "No data found" not in str(problem):
            raise
        raise ValueError(
            f"dataset {name} has its metadata but not its data file (for HDF5, "
            f"{location.data / 'main_data.hdf5'}): copy or make the whole dataset again"
        ) from None
    try:
        yield from storage.get_episodes(range(storage.total_episodes))
    except ImportError as problem:  # e.g. an Arrow dataset without pyarrow
        raise ValueError(
            f"dataset {name} needs a package that is not installed ({problem}); "
            "`pip install 'minari[arrow]'` reads Arrow datasets"
        ) from None
    except (OSError, KeyError) as problem:
        raise ValueError(f"dataset {name} is not a readable Minari dataset ({problem})") from None


def _flat_rows(values: Any, name: str | Path, what: str) -> np.ndarray:
    """A Box space's rows as (steps, size) float32; other spaces are refused."""
    if isinstance(values, dict | tuple | list):
        raise ValueError(
            f"dataset {name} has {what} of a composite (Dict or Tuple) space; seqrank reads "
            "datasets whose observations and actions are flat arrays (Box spaces)"
        )
    rows = np.asarray(values)
    if rows.ndim == 1:  # a Discrete space, or one number a step
        if np.issubdtype(rows.dtype, np.integer):
            raise ValueError(
                f"dataset {name} has Discrete {what}; seqrank reads continuous (Box) ones"
            )
        rows = rows[:, None]
    return rows.reshape(len(rows), -1).astype(np.float32)


def episode_successes(name_or_path: str | Path) -> np.ndarray | None:
    """Whether each episode succeeded at some step, where the dataset recorded success
    (`success` or `is_success` in its infos); None where it did not."""
    location, _ = read_metadata(name_or_path)
    found = []
    for episode in _minari_episodes(location, name_or_path):
        infos = episode.get("infos") or {}
        flags = infos.get("success", infos.get("is_success"))
        if flags is None:
            return None
        found.append(bool(np.any(flags)))
    return np.array(found, bool)


def episodes_with_states(name_or_path: str | Path, task: str | None = None) -> list[Episode]:
    """The dataset's episodes (checked as `load_dataset` checks them) with the physics
    state each step began from and Meta-World's task index: what the labelling page
    renders clips from. A ValueError where the dataset recorded no states."""
    dataset = load_dataset(name_or_path, task)
    location, _ = read_metadata(name_or_path)
    episodes = dataset.episodes()
    raw = (e for e in _minari_episodes(location, name_or_path) if len(e["rewards"]))
    all_infos = [stored.get("infos") or {} for stored in raw]
    stateless = sum("state" not in infos for infos in all_infos)
    if stateless:
        some = (
            "" if stateless == len(episodes) else f" in {stateless} of its {len(episodes)} episodes"
        )
        raise ValueError(
            f"dataset {name_or_path} holds no physics states{some}, from which the page "
            "renders its clips: label a dataset made by `seqrank dataset make` from "
            "random or scripted play of a MuJoCo task (or from a run that recorded states)"
        )
    for episode, infos in zip(episodes, all_infos, strict=True):
        episode.states = np.asarray(infos["state"])[: len(episode.reward)]
        if "task_index" in infos:
            episode.context = int(np.asarray(infos["task_index"])[0])
    return episodes
