"""Trajectory pools: real episodes of one task that span skill levels, saved for reuse.

A pool is the episodes of a true-reward training run (`seqrank train --reward true`: its
first episode is random play, then the agent improves) plus extra episodes of uniform
random play. It is one compressed `.npz` file:

- `obs` (E, T, obs_dim) float32, `action` (E, T, act_dim) float32, `reward` (E, T) float32:
  the true per-step reward;
- `origin` (E,) int: the episode's index in the training run, or -1 for random play;
- `meta`: a JSON string: format, task, how the pool was made.

Minari's format was considered: its datasets need its own package and storage layout for
what is here three arrays, and nothing in this project reads Minari datasets, so a plain
`.npz` that numpy alone opens is kept.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.envs import make_env
from seqrank.episodes import Episode, EpisodeStore, Segments

FORMAT = "seqrank-pool-1"
RANDOM_PLAY = -1


@dataclass(frozen=True)
class Pool:
    task: str
    obs: np.ndarray
    action: np.ndarray
    reward: np.ndarray
    origin: np.ndarray
    meta: dict[str, Any]

    def __len__(self) -> int:
        return len(self.reward)

    @property
    def returns(self) -> np.ndarray:
        return self.reward.sum(1)

    def store(self, which: np.ndarray) -> EpisodeStore:
        """The chosen episodes as an episode store (what sessions cut segments from)."""
        store = EpisodeStore(max(len(which), 1))
        for e in which:
            store.add(Episode(self.obs[e], self.action[e], self.reward[e].astype(np.float64)))
        return store

    def split(self, heldout_every: int = 4) -> tuple[np.ndarray, np.ndarray]:
        """(train, held-out) episode indices: every `heldout_every`-th episode by return
        rank is held out, so both halves span the same skill levels."""
        by_return = np.argsort(self.returns, kind="stable")
        held = np.zeros(len(self), bool)
        held[by_return[heldout_every // 2 :: heldout_every]] = True
        return np.flatnonzero(~held), np.flatnonzero(held)

    def heldout_segments(self, which: np.ndarray, count: int, length: int) -> Segments:
        """A fixed sample of segments of the held-out episodes (the same for every cell)."""
        return self.store(which).sample_segments(count, length, np.random.default_rng(2023))


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
        meta=np.array(meta),
    )
    return path


def load_pool(path: Path | str) -> Pool:
    """A saved pool; a ValueError names the file and what is wrong with it."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(
            f"pool {path} does not exist; build one with `seqrank reward-bench pool --task "
            "TASK --out FILE`"
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in ("obs", "action", "reward", "origin", "meta")}
    except (OSError, ValueError, KeyError) as problem:
        raise ValueError(f"{path} is not a seqrank pool ({problem})") from None
    meta = json.loads(str(arrays["meta"]))
    if meta.get("format") != FORMAT:
        raise ValueError(f"{path}: pool format {meta.get('format')!r}; this reads {FORMAT}")
    task = meta.pop("task")
    meta.pop("format")
    return Pool(task, arrays["obs"], arrays["action"], arrays["reward"], arrays["origin"], meta)


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
    """A pool of a run's episodes (indices from `first_index`) and random-play ones."""
    episodes = [*trained, *extra_random]
    lengths = {len(e.reward) for e in episodes}
    if len(lengths) != 1:
        raise ValueError(f"episodes of {task} differ in length ({sorted(lengths)})")
    origin = [first_index + k for k in range(len(trained))] + [RANDOM_PLAY] * len(extra_random)
    return Pool(
        task,
        np.stack([e.obs for e in episodes]).astype(np.float32),
        np.stack([e.action for e in episodes]).astype(np.float32),
        np.stack([e.reward for e in episodes]).astype(np.float32),
        np.array(origin),
        meta,
    )


def pool_from_run(
    run_path: Path, random_count: int, seed: int, until_step: int | None = None
) -> Pool:
    """The episodes kept in a run's last checkpoint (with `until_step`, only those that
    ended by that step: the pool of a shorter run of the same settings), with
    `random_count` random ones."""
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
        "random_episodes": random_count,
        "random_seed": seed,
    }
    extra = random_episodes(config.task, random_count, seed)
    return pool_from_episodes(config.task, kept, first, extra, meta)


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
