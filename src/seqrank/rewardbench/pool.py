"""Trajectory pools: real episodes of one task that span skill levels, saved for reuse.

A pool is the episodes of a true-reward training run (`seqrank train --reward true`: its
first episode is random play, then the agent improves) plus extra episodes of uniform
random play. It is one compressed `.npz` file:

- `obs` (E, T, obs_dim) float32, `action` (E, T, act_dim) float32, `reward` (E, T) float32:
  the true per-step reward; T is the longest episode's length;
- `length` (E,) int: each episode's steps. Episodes may end early (a terminal state, as
  Gymnasium's MuJoCo tasks have): the steps after an episode's end are zeros, never read;
- `origin` (E,) int: the episode's index in the training run, or -1 for random play;
- `meta`: a JSON string: format, task, how the pool was made.

Format 1 (no `length`: every episode T steps) is still read.

Segments are cut as in a training run (`EpisodeStore.sample_segments`), so each lies within
one episode: a uniform episode, then a uniform start within it; an episode shorter than
the segment gives its whole self, padded with its last step at zero true reward (what an
absorbing terminal state would show). Short episodes are thus drawn as often as long ones.

A pool is kept as a plain `.npz` that numpy alone opens; an offline dataset (Minari's
format, `seqrank dataset make`) becomes one with `pool_from_dataset`, so the benchmark
scores labels on that dataset's segments (`reward-bench pool --from-dataset`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.envs import make_env
from seqrank.episodes import Episode, EpisodeStore, Segments
from seqrank.offline.dataset import OfflineDataset

FORMAT = "seqrank-pool-2"
FORMATS = ("seqrank-pool-1", FORMAT)  # those this reads: 1 has no `length`
RANDOM_PLAY = -1
HELDOUT_EVERY = 4  # every 4th episode by return rank is held out, from the 3rd on
MIN_EPISODES = HELDOUT_EVERY // 2 + 1  # the fewest with one held out (and two to train on)


@dataclass(frozen=True)
class Pool:
    task: str
    obs: np.ndarray
    action: np.ndarray
    reward: np.ndarray
    origin: np.ndarray
    meta: dict[str, Any]
    length: np.ndarray  # (E,) steps of each episode; the rest of its row is padding

    def __len__(self) -> int:
        return len(self.reward)

    @property
    def returns(self) -> np.ndarray:
        return self.reward.sum(1)  # the padding is zero reward

    def store(self, which: np.ndarray) -> EpisodeStore:
        """The chosen episodes as an episode store (what sessions cut segments from)."""
        store = EpisodeStore(max(len(which), 1))
        for e in which:
            steps = int(self.length[e])
            reward = self.reward[e, :steps].astype(np.float64)
            store.add(Episode(self.obs[e, :steps], self.action[e, :steps], reward))
        return store

    def split(self) -> tuple[np.ndarray, np.ndarray]:
        """(train, held-out) episode indices: every `HELDOUT_EVERY`-th episode by return
        rank is held out, so both halves span the same skill levels."""
        by_return = np.argsort(self.returns, kind="stable")
        held = np.zeros(len(self), bool)
        held[by_return[HELDOUT_EVERY // 2 :: HELDOUT_EVERY]] = True
        return np.flatnonzero(~held), np.flatnonzero(held)

    def margin(self, which: np.ndarray, segment_length: int) -> float:
        """B-Pref's margin: the episodes' mean return scaled to a segment (per step of
        their mean length, which episodes that end early make shorter than T)."""
        mean_length = float(self.length[which].mean())
        return float(self.returns[which].mean()) * segment_length / mean_length

    def heldout_segments(self, which: np.ndarray, count: int, length: int) -> Segments:
        """A fixed sample of segments of the held-out episodes (the same for every cell)."""
        return self.store(which).sample_segments(count, length, np.random.default_rng(2023))


def check_pool_size(episodes: int, what: str) -> None:
    """A pool too small to hold an episode out is refused, naming what it has and needs."""
    if episodes < MIN_EPISODES:
        raise ValueError(
            f"{what} has {episodes} episode{'s' * (episodes != 1)}; a pool needs at least "
            f"{MIN_EPISODES}, so that one is held out to measure on (every {HELDOUT_EVERY}th "
            f"by return, from rank {MIN_EPISODES} on): build it with more episodes "
            "(`reward-bench pool` with --random-episodes, or from a run with more finished "
            "episodes)"
        )


def save_pool(pool: Pool, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = json.dumps({"format": FORMAT, "task": pool.task, **pool.meta})
    np.savez_compressed(
        path,
        obs=pool.obs.astype(np.float32),
        action=pool.action.astype(np.float32),
        reward=pool.reward.astype(np.float32),
        origin=pool.origin.astype(np.int64),
        length=pool.length.astype(np.int64),
        meta=np.array(meta),
    )
    return path


def load_pool(path: Path | str) -> Pool:
    """A saved pool; a ValueError names the file and what is wrong with it (a pool too
    small to hold an episode out, too)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(
            f"pool {path} does not exist; build one with `seqrank reward-bench pool --task "
            "TASK --out FILE`"
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in ("obs", "action", "reward", "origin", "meta")}
            meta = json.loads(str(arrays["meta"]))
            if meta.get("format") not in FORMATS:
                accepted = ", ".join(FORMATS)
                raise ValueError(f"pool format {meta.get('format')!r}; this reads {accepted}")
            steps = arrays["reward"].shape[1]
            length = data["length"] if "length" in data else np.full(len(arrays["reward"]), steps)
    except (OSError, ValueError, KeyError) as problem:
        raise ValueError(f"{path} is not a seqrank pool ({problem})") from None
    check_pool_size(len(length), f"pool {path}")
    task = meta.pop("task")
    meta.pop("format")
    obs, action, reward, origin = (arrays[k] for k in ("obs", "action", "reward", "origin"))
    return Pool(task, obs, action, reward, origin, meta, length)


def random_episodes(task: str, count: int, seed: int) -> list[Episode]:
    """Episodes of uniform random actions, each seeded from `seed` and its index."""
    env = make_env(task, seed)
    rng = np.random.default_rng([seed, 7])
    episodes = []
    for _ in range(count):
        obs, _ = env.reset(seed=int(rng.integers(2**31)))
        rows: tuple[list[np.ndarray], list[np.ndarray], list[float]] = ([], [], [])
        done = False
        while not done:
            action = rng.uniform(-1.0, 1.0, env.act_dim).astype(np.float32)
            next_obs, reward, terminated, truncated, _ = env.step(action)
            rows[0].append(obs)
            rows[1].append(env.canonical_action(action))
            rows[2].append(float(reward))
            obs, done = next_obs, bool(terminated or truncated)
        episodes.append(Episode(np.array(rows[0]), np.array(rows[1]), np.array(rows[2])))
    return episodes


def pool_from_episodes(
    task: str,
    trained: list[Episode],
    first_index: int,
    extra_random: list[Episode],
    meta: dict[str, Any],
) -> Pool:
    """A pool of a run's episodes (indices from `first_index`) and random-play ones; they
    may differ in length (episodes that end early), each row padded to the longest."""
    episodes = [*trained, *extra_random]
    check_pool_size(len(episodes), f"the pool of {task}")
    origin = [first_index + k for k in range(len(trained))] + [RANDOM_PLAY] * len(extra_random)
    length = np.array([len(e.reward) for e in episodes])
    return Pool(
        task,
        _padded([e.obs for e in episodes], length.max()),
        _padded([e.action for e in episodes], length.max()),
        _padded([e.reward for e in episodes], length.max()),
        np.array(origin),
        meta,
        length,
    )


def _padded(rows: list[np.ndarray], steps: int) -> np.ndarray:
    """Each episode's rows followed by zeros up to `steps`, stacked (float32)."""
    out = np.zeros((len(rows), steps, *rows[0].shape[1:]), np.float32)
    for k, row in enumerate(rows):
        out[k, : len(row)] = row
    return out


def pool_from_dataset(dataset: OfflineDataset, random_count: int, seed: int) -> Pool:
    """An offline dataset's episodes (origin: their index in the dataset) with
    `random_count` episodes of random play."""
    episodes = dataset.episodes()
    check_pool_size(len(episodes) + random_count, f"dataset {dataset.meta.get('dataset_id')}")
    extra = random_episodes(dataset.task, random_count, seed)
    meta = {"dataset": dataset.meta.get("dataset_id"), "dataset_path": dataset.meta.get("path"),
            "random_episodes": random_count, "random_seed": seed}  # fmt: skip
    return pool_from_episodes(dataset.task, episodes, 0, extra, meta)


@dataclass(frozen=True)
class KeptEpisodes:
    """The episodes a run's checkpoint kept, as a pool takes them."""

    task: str
    episodes: list[Episode]
    first_index: int  # the run's number of the first one
    meta: dict[str, Any]  # how they were taken

    def check_size(self, random_count: int) -> None:
        """A ValueError if these and `random_count` random episodes are too few a pool."""
        check_pool_size(len(self.episodes) + random_count, f"the pool of run {self.meta['run']}")


def kept_episodes(run_path: Path, until_step: int | None = None) -> KeptEpisodes:
    """The episodes kept in a run's last checkpoint (with `until_step`, only those that
    ended by that step: the pool of a shorter run of the same settings). A ValueError (or
    FileNotFoundError: no run there) names what is wrong with the run."""
    from seqrank.training.runs import RunDir

    run = RunDir.open(run_path)
    state = run.load_checkpoint()
    if state is None:
        raise ValueError(f"run {run_path} has no checkpoint to take episodes from")
    config = run.read_config()
    kept: list[Episode] = list(state["episodes"]["episodes"])
    first = int(state["counters"]["episode"]) - len(kept)
    steps = int(state["counters"]["step"])
    if until_step is not None:
        kept, steps = _ended_by(kept, first, steps, until_step, run_path)
    meta = {
        "run": str(run_path),
        "run_reward": str(config.reward),
        "run_steps": steps,  # with until_step: the end of the last episode taken
        "until_step": until_step,
        "run_seed": config.seed,
    }
    return KeptEpisodes(config.task, kept, first, meta)


def pool_from_kept(kept: KeptEpisodes, random_count: int, seed: int) -> Pool:
    """The kept episodes with `random_count` episodes of random play."""
    kept.check_size(random_count)  # before playing the random episodes
    extra = random_episodes(kept.task, random_count, seed)
    meta = {**kept.meta, "random_episodes": random_count, "random_seed": seed}
    return pool_from_episodes(kept.task, kept.episodes, kept.first_index, extra, meta)


def pool_from_run(
    run_path: Path, random_count: int, seed: int, until_step: int | None = None
) -> Pool:
    """A run's kept episodes (see `kept_episodes`) with `random_count` random ones."""
    return pool_from_kept(kept_episodes(run_path, until_step), random_count, seed)


def _ended_by(
    kept: list[Episode], first: int, steps: int, until_step: int, run_path: Path
) -> tuple[list[Episode], int]:
    """The kept episodes that ended by `until_step`, and that step. Episode ends are
    counted from the run's start, so every earlier episode must still be kept."""
    if first > 0:
        raise ValueError(
            f"run {run_path} dropped its first {first} episodes (episodes_kept): the step "
            "each kept one ended at is unknown, so --until-step cannot be applied"
        )
    if until_step > steps:
        raise ValueError(f"--until-step {until_step} is past the run's last step ({steps})")
    ends = np.cumsum([len(e.reward) for e in kept])
    count = int(np.searchsorted(ends, until_step, side="right"))
    if count == 0:
        raise ValueError(f"no episode of run {run_path} ended by step {until_step}")
    return kept[:count], int(ends[count - 1])
