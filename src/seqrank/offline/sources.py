"""Where a dataset's episodes come from: a seqrank run's kept episodes, Meta-World's
scripted policies with Gaussian action noise, uniform random play, or a mixture of them.

A source is written `random`, `scripted` (the noise of `--noise`), `scripted:SIGMA` or
`run:PATH`, optionally followed by `=SHARE`: `--source scripted=0.7 --source random`
shares `--episodes` between them, 70% and the 30% the shares leave (sources without a
share split the rest equally; shares over 1, or under 1 with no source to take the rest,
are refused; counts by largest remainder, each source's episodes in turn). Episodes are
played through seqrank's own environments (`make_env`), so the observations are those
seqrank's agents see; each played episode begins from its own reset seed, drawn from
`--seed` and the source's place in the list.

A run's episodes are those its last checkpoint kept (`rewardbench.pool.kept_episodes`),
a true-reward or preference run's replay ("medium-replay" in LiRE's sense): all of them
when it is the only source and no `--episodes` is given, else that many spread evenly
over the run (so a part still spans its skill levels). A run keeps no observation after
an episode's last action, so that one is its last observation repeated; its last step is a
termination where the episode ended before the task's time limit, else a truncation.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.episodes import Episode
from seqrank.offline.minari_write import PlayedEpisode

KINDS = ("random", "scripted", "run:PATH")
ACCEPTED = "random, scripted, scripted:SIGMA or run:PATH, each optionally =SHARE"


@dataclass(frozen=True)
class Source:
    kind: str  # random, scripted or run
    share: float | None = None  # of --episodes; None: an equal share
    noise: float | None = None  # scripted: the action noise's SD (None: --noise)
    run: Path | None = None  # run: the run's folder

    def describe(self, noise: float) -> str:
        if self.kind == "scripted":
            return f"scripted (noise {self.noise if self.noise is not None else noise:g})"
        return f"run {self.run}" if self.kind == "run" else self.kind


def parse_source(text: str) -> Source:
    """`random`, `scripted`, `scripted:SIGMA` or `run:PATH`, each optionally `=SHARE`; a
    ValueError names the bad value and what is accepted."""
    body, share = text, None
    head, equals, tail = text.rpartition("=")
    if equals:
        try:
            share = float(tail)
        except ValueError:
            raise ValueError(f"source {text!r}: share {tail!r} is not a number") from None
        if not np.isfinite(share) or share <= 0:
            raise ValueError(f"source {text!r}: its share must be a number > 0, got {tail}")
        body = head
    kind, colon, argument = body.partition(":")
    if kind == "random" and not colon:
        return Source("random", share)
    if kind == "scripted":
        if not colon:
            return Source("scripted", share)
        return Source("scripted", share, noise=_noise(argument, text))
    if kind == "run" and argument:
        return Source("run", share, run=Path(argument))
    raise ValueError(f"unknown source {text!r}; accepted: {ACCEPTED}")


def _noise(value: str, text: str) -> float:
    try:
        noise = float(value)
    except ValueError:
        noise = -1.0
    if not np.isfinite(noise) or noise < 0:
        raise ValueError(f"source {text!r}: the noise must be a number >= 0, got {value!r}")
    return noise


def episode_counts(sources: list[Source], episodes: int) -> list[int]:
    """`episodes` shared between the sources by their shares, by largest remainder;
    sources without a share split equally what the others leave. A ValueError where the
    shares do not add up (see `source_weights`) or a source would get none."""
    exact = episodes * source_weights(sources)
    counts = np.floor(exact).astype(int)
    by_remainder = np.argsort(-(exact - counts), kind="stable")
    counts[by_remainder[: episodes - counts.sum()]] += 1
    if np.any(counts == 0):
        raise ValueError(
            f"--episodes {episodes} gives no episode to some source ({counts.tolist()} for "
            f"{len(sources)} sources): ask for more episodes or fewer sources"
        )
    return [int(c) for c in counts]


def source_weights(sources: list[Source]) -> np.ndarray:
    """Each source's fraction of the episodes: its share, or an equal part of what the
    shares leave (all equal where none is given); shares above 1 in all, or below 1 with
    no source to take the rest, are refused rather than scaled."""
    given = [s.share for s in sources if s.share is not None]
    total, unshared = float(sum(given)), len(sources) - len(given)
    problem = None
    if total > 1 + _SLACK:
        problem = "more than 1"
    elif unshared and total >= 1 - _SLACK:
        problem = "1, leaving nothing for the sources without a share"
    elif not unshared and total < 1 - _SLACK:
        problem = "less than 1, and no source without a share takes the rest"
    if problem:
        listed = " + ".join(f"{share:g}" for share in given)
        raise ValueError(
            f"the source shares sum to {listed} = {total:g}, {problem}; accepted: shares "
            "that sum to 1, or to less with sources without a share splitting the rest"
        )
    rest = (1.0 - total) / unshared if unshared else 0.0
    weights = np.array([s.share if s.share is not None else rest for s in sources])
    return weights / weights.sum()  # exactly 1 in all (0.1 + 0.2 is not 0.3)


_SLACK = 1e-9  # shares written as decimals (0.1 + 0.2) sum to 1 within this


def check_source(source: Source, task: str, count: int | None) -> None:
    """A ValueError for a source the task cannot have (or a run too short for `count`
    episodes), before anything is played."""
    if source.kind == "scripted":
        scripted_policy(task)
    if source.kind == "run":
        _kept_run(source, task, count)


def scripted_policy(task: str) -> Callable[[np.ndarray], np.ndarray]:
    """The task's Meta-World scripted policy (`metaworld.policies`), as obs -> action."""
    from seqrank.envs import canonical_task

    suite, name = canonical_task(task)
    if suite != "metaworld":
        raise ValueError(
            f"source scripted: task {task} has no scripted policy; Meta-World tasks have "
            "(metaworld.policies): use random or run:PATH for this task"
        )
    from metaworld.policies import ENV_POLICY_MAP

    # a concrete class per task (mypy sees the map's abstract base)
    policy = ENV_POLICY_MAP[name]()  # type: ignore[abstract]

    def act(obs: np.ndarray) -> np.ndarray:
        with warnings.catch_warnings():  # "Constant(s) may be too high": they clip, as meant
            warnings.simplefilter("ignore", UserWarning)
            return np.asarray(policy.get_action(obs.astype(np.float64)), np.float64)

    return act


def _run_task(source: Source) -> str:
    import json

    from seqrank.training.runs import RunDir

    config = Path(str(source.run)) / "config.json"
    if config.is_file() and "dataset" in json.loads(config.read_text()):
        raise ValueError(
            f"source run:{source.run} is an offline run, which plays no episodes of its own: "
            "give an online run's folder (seqrank train)"
        )
    try:
        return str(RunDir.open(source.run).read_config().task)  # type: ignore[arg-type]
    except (FileNotFoundError, ValueError) as problem:
        raise ValueError(f"source run:{source.run}: {problem}") from None


def play(
    task: str,
    policy: Callable[[np.ndarray, np.random.Generator], np.ndarray],
    count: int,
    seed_sequence: np.random.SeedSequence,
) -> list[PlayedEpisode]:
    """`count` episodes of `policy` (obs, rng -> action in [-1, 1]), each from its own reset
    seed; the policy's draws come from a stream of the same sequence."""
    from seqrank.envs import make_env

    reset_stream, act_stream = (np.random.default_rng(s) for s in seed_sequence.spawn(2))
    env = make_env(task, int(seed_sequence.generate_state(1)[0]))
    try:
        return [_play_one(env, policy, int(reset_stream.integers(2**31)), act_stream)
                for _ in range(count)]  # fmt: skip
    finally:
        env.close()


def _play_one(
    env: Any,
    policy: Callable[[np.ndarray, np.random.Generator], np.ndarray],
    reset_seed: int,
    rng: np.random.Generator,
) -> PlayedEpisode:
    """One episode, with a row per observation of success and physics state (the reset's
    first: what Minari's infos hold); no states for a task without MuJoCo state (its
    clips are frames, too big to keep: such a dataset cannot be labelled at the page)."""
    keep_states = env.clip_source == "state"
    obs, info = env.reset(seed=reset_seed)
    state = env.get_state() if keep_states else None
    rows: dict[str, list[Any]] = {"obs": [obs], "state": [state], "succ": [False]}
    rows |= {"act": [], "rew": [], "term": []}
    done = truncated = False
    while not done:
        action = np.clip(policy(obs, rng), -1.0, 1.0).astype(np.float32)
        obs, reward, terminated, truncated, step_info = env.step(action)
        done = bool(terminated or truncated)
        state = env.get_state() if keep_states else None
        row = (obs, state, step_info["success"], env.canonical_action(action),
               reward, terminated)  # fmt: skip
        for key, value in zip(rows, row, strict=True):
            rows[key].append(value)
    ends = np.zeros(len(rows["rew"]), bool)
    ends[-1] = bool(truncated) and not rows["term"][-1]
    return PlayedEpisode(
        np.array(rows["obs"], np.float32),
        np.array(rows["act"], np.float32),
        np.array(rows["rew"], np.float64),
        np.array(rows["term"], bool),
        ends,
        np.array(rows["succ"], bool),
        reset_seed,
        np.array(rows["state"], np.float64) if keep_states else None,
        info.get("task_index"),
    )


def random_play(task: str, count: int, seeds: np.random.SeedSequence) -> list[PlayedEpisode]:
    from seqrank.envs import make_env

    env = make_env(task)
    act_dim = env.act_dim
    env.close()
    return play(task, lambda obs, rng: rng.uniform(-1.0, 1.0, act_dim), count, seeds)


def scripted_play(
    task: str, count: int, noise: float, seeds: np.random.SeedSequence
) -> list[PlayedEpisode]:
    act = scripted_policy(task)

    def noisy(obs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        action = act(obs)
        return action + rng.normal(0.0, noise, action.shape)

    return play(task, noisy, count, seeds)


def _kept_run(source: Source, task: str, count: int | None) -> list[Episode]:
    """The run's kept episodes, checked: a run of `task`, with `count` of them at least."""
    from seqrank.offline.minari_io import same_task
    from seqrank.rewardbench.pool import kept_episodes

    run_task = _run_task(source)
    if not same_task(run_task, task):
        raise ValueError(f"source run:{source.run} is a run of {run_task}, not of {task}")
    try:
        kept = kept_episodes(source.run)  # type: ignore[arg-type]
    except FileNotFoundError as problem:
        raise ValueError(f"source run:{source.run}: {problem}") from None
    if not kept.episodes or (count is not None and count > len(kept.episodes)):
        raise ValueError(
            f"source run:{source.run} kept {len(kept.episodes)} episodes; "
            f"{count if count is not None else 'at least one'} asked of it: ask for fewer "
            "episodes (--episodes, or a smaller share)"
        )
    return kept.episodes


def run_episodes(source: Source, task: str, count: int | None) -> list[PlayedEpisode]:
    """A run's kept episodes (all of them, or `count` spread evenly over the run)."""
    from seqrank.envs import make_env

    chosen = _kept_run(source, task, count)
    if count is not None:
        which = np.unique(np.linspace(0, len(chosen) - 1, count).round().astype(int))
        chosen = [chosen[i] for i in which]
    env = make_env(task)
    limit = env.episode_length
    env.close()
    out = []
    for episode in chosen:
        steps = len(episode.reward)
        last = np.zeros(steps, bool)
        last[-1] = True
        ended_early = steps < limit
        out.append(
            PlayedEpisode(
                np.concatenate([episode.obs, episode.obs[-1:]]).astype(np.float32),
                episode.action.astype(np.float32),
                episode.reward.astype(np.float64),
                last & ended_early,
                last & ~ended_early,
                None,
                None,
                None
                if episode.states is None
                else np.concatenate([episode.states, episode.states[-1:]]),
                episode.context,
            )
        )
    return out
