"""The Python API: what `import seqrank` offers (see the README's "Python API").

- Ask: `run_scheme` runs a comparison scheme over your own `ask(first, second)` function,
  and `close_preferences` adds every label that transitivity implies.
- Train: `make_config` resolves a run's settings like `seqrank train`, `train` runs it,
  optionally with your own feedback source (`JudgeSource` wraps a plain function that
  compares two segments).
- Look: `load_run` reads a run directory (settings, metrics, summary) and its policy.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.agents.protocol import Policy
from seqrank.config import TrainConfig, resolve_config
from seqrank.envs import SimEnv, make_env
from seqrank.episodes import Segments
from seqrank.feedback.checking import Recheck
from seqrank.feedback.closure import Augmentation, augment
from seqrank.feedback.schemes import SessionRecord, get_scheme, uniform_choice
from seqrank.feedback.session import FeedbackSource, SessionRequest
from seqrank.types import Answer, AnsweredQuestion


def run_scheme(
    scheme: str,
    pool_size: int,
    budget: int,
    ask: Callable[[int, int], Answer],
    seed: int = 0,
    recheck: Recheck | None = None,
) -> SessionRecord:
    """Ask `budget` questions about segments `0 .. pool_size - 1` the way `scheme`
    (pairwise, sequential, root or ranked) asks them. `ask(first, second)` gets two
    segment ids and returns an `Answer`; in schemes with a defender, `first` is it.
    With a `Recheck` (noise-aware augmentation) answers that would imply many pairs are
    asked again within the budget; for the same teacher's next session pass
    `recheck.after(record.answers)`, which remembers whether they contradicted themselves."""
    rng = np.random.default_rng(seed)
    return get_scheme(scheme)(pool_size, budget, ask, rng, uniform_choice, recheck)


def close_preferences(
    answers: Iterable[AnsweredQuestion],
    true_returns: list[float] | None = None,
    path_unchecked: int | None = None,
    vouched: Collection[tuple[int, int]] = frozenset(),
) -> Augmentation:
    """The answered pairs plus every pair they imply by transitivity (segments caught in a
    preference cycle imply nothing; with `path_unchecked`, only along paths with at most
    that many unconfirmed answers; `vouched` (winner, loser) answers count as confirmed,
    as a session's `SessionRecord.vouched` gives them). With `true_returns` (per segment
    id) the stats count the labels those returns contradict."""
    return augment(answers, true_returns, path_unchecked, vouched)


def make_config(task: str | None = None, scale: str = "small", **settings: Any) -> TrainConfig:
    """A run's settings as `seqrank train --task TASK --scale SCALE --KEY VALUE ...` would
    resolve them (no task: walker_walk, or a `teacher="replay:FILE"` file's task; the
    settings the file fixes are taken from it); a ValueError names a bad value or an
    unknown setting."""
    known = {f.name for f in fields(TrainConfig)}
    unknown = sorted(set(settings) - known)
    if unknown:
        raise ValueError(
            f"unknown setting {unknown[0]!r}; settings are TrainConfig's fields, the options "
            "of `seqrank train` with _ for - (see help(seqrank.TrainConfig))"
        )
    return resolve_config(task, scale, settings)


@dataclass(frozen=True)
class Segment:
    """One segment a judge compares: what the reward model sees and the simulator's truth."""

    features: np.ndarray  # (steps, obs_dim + act_dim): observation, then action
    rewards: np.ndarray  # (steps,) the true per-step reward
    obs_dim: int

    @property
    def observations(self) -> np.ndarray:
        return self.features[:, : self.obs_dim]

    @property
    def actions(self) -> np.ndarray:
        return self.features[:, self.obs_dim :]


class JudgeSource:
    """A feedback source from a function `judge(first, second) -> Answer` that compares two
    `Segment`s: a model that judges clips, a rule, another interface."""

    def __init__(self, judge: Callable[[Segment, Segment], Answer], obs_dim: int):
        self.judge, self.obs_dim = judge, obs_dim

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        if obs_dim != self.obs_dim:
            raise ValueError(f"this judge reads {self.obs_dim} observations; {task} has {obs_dim}")

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        segments = request.segments

        def ask(first: int, second: int) -> Answer:
            one = Segment(segments.features[first], segments.rewards[first], self.obs_dim)
            two = Segment(segments.features[second], segments.rewards[second], self.obs_dim)
            verdict = self.judge(one, two)
            if not isinstance(verdict, Answer):
                raise TypeError(
                    f"the judge returned {verdict!r}; accepted: a seqrank.Answer (FIRST, "
                    "SECOND, EQUAL or SKIP)"
                )
            return verdict

        return segments, request.run_scheme(ask)


def train(
    config: TrainConfig,
    out: Path | str,
    source: FeedbackSource | None = None,
    progress: Callable[[int, dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Train a run into the new directory `out` (or continue it, when `out` holds a stopped
    run of the same settings; a finished one is returned as it is) and return its summary.
    `source` answers the questions in place of the config's teacher; `progress(step, live)`
    is called every 100 steps. The directory is locked while it trains (ValueError when
    another process holds it; a run of other settings is refused naming what differs)."""
    from seqrank.training.launch import open_or_start
    from seqrank.training.runs import RunDir
    from seqrank.training.runtime import resolve_device
    from seqrank.training.trainer import Trainer

    def factory(settings: TrainConfig, run: RunDir) -> Trainer:
        return Trainer(settings, run, progress, source)

    device = str(resolve_device(config.device))
    started = open_or_start(Path(out), config, device, factory)
    try:
        if started.finished:
            return started.run.read_summary()
        summary: dict[str, Any] = started.trainer.train()
        return summary
    finally:
        started.run.release()


@dataclass(frozen=True)
class Run:
    """A run directory, read: its settings, metric rows and summary (None while unfinished)."""

    path: Path
    config: TrainConfig
    metrics: list[dict[str, Any]]
    summary: dict[str, Any] | None

    def evaluations(self) -> list[tuple[int, float]]:
        """(step, mean evaluation return) of every evaluation so far."""
        return [(r["step"], r["eval_return"]) for r in self.metrics if r["kind"] == "eval"]

    def environment(self, seed: int | None = None) -> SimEnv:
        return make_env(self.config.task, self.config.seed if seed is None else seed)

    def policy(self) -> Policy:
        """The agent of the last checkpoint, on the CPU: `policy.act(obs, True, generator)`
        gives the deterministic action."""
        from seqrank.training.agent_factory import load_policy

        return load_policy(self.path, self.environment())


def load_run(path: Path | str) -> Run:
    """Read a run directory written by `seqrank train` or `train`."""
    from seqrank.training.runs import RunDir

    run = RunDir.open(Path(path))
    summary = run.read_summary() if (run.path / "summary.json").exists() else None
    return Run(run.path, run.read_config(), run.read_metrics(), summary)
