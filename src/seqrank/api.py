"""The Python API: what `import seqrank` offers (docs/reference/api.md).

- Ask: `run_scheme` runs a comparison scheme over your own `ask(first, second)` function,
  and `close_preferences` adds every label that transitivity implies.
- Train: `make_config` resolves a run's settings like `seqrank train`, `train` runs it,
  optionally with your own feedback source (`JudgeSource` wraps a plain function that
  compares two segments).
- Offline: `offline_train` learns a policy from a fixed dataset (IQL).
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
    """Ask `budget` questions about segments `0 .. pool_size - 1` the way `scheme` asks them.

    The scheme picks which two segments each question compares; `ask` answers, so a
    person, another interface or a model can stand behind it. The budget counts the
    questions asked, skips and re-checks included.

    Args:
        scheme: pairwise, sequential, root or ranked (`seqrank.SCHEMES`); ValueError
            names the accepted ones.
        pool_size: the segments to draw from; ValueError when the scheme needs more
            (pairwise 2 x budget, sequential and root budget + 1, ranked 2).
        budget: the questions to ask, at least 1.
        ask: `ask(first, second)` gets two segment ids and returns an `Answer`; in
            schemes with a defender (sequential, root), `first` is it.
        seed: seeds which segments are drawn; the same seed and answers give the same
            session.
        recheck: noise-aware augmentation: an answer that would imply many pairs is
            asked again within the budget and stands only if the repeats agree. For the
            same teacher's next session pass `recheck.after(record.answers)`, which
            remembers whether they contradicted themselves. None: answers stand as given.

    Returns:
        The `SessionRecord`: `answers` (questions and answers, in order), `segments`
            (the ids drawn), `vouched` (answers the `recheck`'s model agreed with) and
            `asked`.

    Examples:
        >>> import seqrank
        >>> value = [3.0, 1.0, 2.0, 5.0, 4.0]  # this teacher prefers the larger value
        >>> def ask(first, second):
        ...     better = value[first] > value[second]
        ...     return seqrank.Answer.FIRST if better else seqrank.Answer.SECOND
        >>> record = seqrank.run_scheme("sequential", pool_size=5, budget=3, ask=ask)
        >>> record.asked, len(record.segments)
        (3, 4)
    """
    rng = np.random.default_rng(seed)
    return get_scheme(scheme)(pool_size, budget, ask, rng, uniform_choice, recheck)


def close_preferences(
    answers: Iterable[AnsweredQuestion],
    true_returns: list[float] | None = None,
    path_unchecked: int | None = None,
    vouched: Collection[tuple[int, int]] = frozenset(),
) -> Augmentation:
    """The answered pairs plus every pair they imply by transitivity.

    If a beats b and b beats c, a beats c is inferred. Segments caught in a preference
    cycle (a noisy teacher) imply nothing; equal answers are never chained.

    Args:
        answers: the answered questions, e.g. a `SessionRecord`'s `answers`.
        true_returns: the true return of each segment id, to count the labels it
            contradicts (`stats.asked_wrong`, `stats.inferred_wrong`); None: those are None.
        path_unchecked: infer only along paths of at most this many unconfirmed answers
            (an answer is confirmed by an agreeing re-check, `Recheck`); None: every path.
        vouched: (winner, loser) answers that count as confirmed, as a session's
            `SessionRecord.vouched` gives them.

    Returns:
        An `Augmentation`: `pairs` (`LabelledPair`s, asked and `inferred`) and `stats`.

    Examples:
        >>> import seqrank
        >>> first = lambda a, b: seqrank.Answer.FIRST  # each defender beats its challenger
        >>> record = seqrank.run_scheme("sequential", pool_size=5, budget=4, ask=first)
        >>> closed = seqrank.close_preferences(record.answers)  # one chain of 5 segments
        >>> closed.stats.answered, closed.stats.inferred, len(closed.pairs)
        (4, 6, 10)
    """
    return augment(answers, true_returns, path_unchecked, vouched)


def make_config(task: str | None = None, scale: str = "small", **settings: Any) -> TrainConfig:
    """A run's settings, resolved as `seqrank train --task TASK --scale SCALE ...` would.

    The suite's defaults, then the task's row of the paper's Table 2, then the size
    preset, then `settings`; validated like the command line (a ValueError names a bad
    value or an unknown setting, and what is accepted).

    Args:
        task: a task name as `--task` takes it; None: walker_walk, or the task of a
            `teacher="replay:FILE"` file (the settings the file fixes are taken from it).
        scale: small (the default: a preset sized for a 2-core CPU), paper (the
            paper's Table 2 sizes) or auto (paper on CUDA, small elsewhere, as
            `seqrank train` and `PreferenceFeedback` default to).
        **settings: `TrainConfig` fields, the options of `seqrank train` with _ for -.

    Returns:
        The frozen `TrainConfig`.

    Examples:
        >>> import seqrank
        >>> config = seqrank.make_config("walker_walk", scheme="root", steps=60_000)
        >>> print(config.scheme, config.steps, config.hidden)  # hidden: the small preset's
        root 60000 256
    """
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
    """One segment a judge compares: what the reward model sees and the simulator's truth.

    Attributes:
        features: (steps, obs_dim + act_dim): each step's observation, then its action.
        rewards: (steps,) the true per-step reward (a judge that reads it is a script).
        obs_dim: where `features` splits into `observations` and `actions`.

    Examples:
        >>> import numpy as np, seqrank
        >>> segment = seqrank.Segment(np.zeros((50, 4)), rewards=np.ones(50), obs_dim=3)
        >>> segment.observations.shape, segment.actions.shape, float(segment.rewards.sum())
        ((50, 3), (50, 1), 50.0)
    """

    features: np.ndarray  # (steps, obs_dim + act_dim): observation, then action
    rewards: np.ndarray  # (steps,) the true per-step reward
    obs_dim: int

    @property
    def observations(self) -> np.ndarray:
        """(steps, obs_dim): each step's observation."""
        return self.features[:, : self.obs_dim]

    @property
    def actions(self) -> np.ndarray:
        """(steps, act_dim): each step's action."""
        return self.features[:, self.obs_dim :]


class JudgeSource:
    """A feedback source from a function that compares two `Segment`s.

    `train(config, out, source=JudgeSource(judge, obs_dim))` asks `judge` every question of
    the run in place of the config's teacher: a model that judges clips, a rule, another
    interface. The scheme, the augmentation and the labels stay the run's own.

    Args:
        judge: `judge(first, second)` returns an `Answer` (FIRST, SECOND, EQUAL or SKIP;
            anything else stops the run with a TypeError).
        obs_dim: the task's observation size (`make_env(task).obs_dim`); a run on a task
            of another size is refused before it starts.

    Examples:
        >>> import seqrank
        >>> def judge(first, second):  # the larger true return wins, as a script would
        ...     better = first.rewards.sum() > second.rewards.sum()
        ...     return seqrank.Answer.FIRST if better else seqrank.Answer.SECOND
        >>> source = seqrank.JudgeSource(judge, seqrank.make_env("walker_walk").obs_dim)
        >>> source.check_compatible("dmc:cartpole_swingup", obs_dim=5, act_dim=1)
        Traceback (most recent call last):
        ValueError: this judge reads 24 observations; dmc:cartpole_swingup has 5
    """

    def __init__(self, judge: Callable[[Segment, Segment], Answer], obs_dim: int):
        self.judge, self.obs_dim = judge, obs_dim

    def has_session(self, session: int) -> bool:
        """Always True: a function answers as many sessions as the run asks."""
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        """ValueError when `task`'s observations are not of the judge's size."""
        if obs_dim != self.obs_dim:
            raise ValueError(f"this judge reads {self.obs_dim} observations; {task} has {obs_dim}")

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        """The request's scheme over its pool, each question put to `judge`."""
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
    """Train a run into the directory `out` and return its summary.

    A new `out` starts the run; one that holds a stopped run of the same settings
    continues it (a finished one is returned as it is; a run of other settings is refused,
    naming what differs). The directory is locked while it trains: ValueError when another
    process holds it. `load_run(out)` reads the result, its policy included.

    Args:
        config: the run's settings (`make_config`).
        out: the run directory: config.json, metrics.jsonl, the labels, checkpoints and,
            once finished, summary.json.
        source: who answers the questions in place of the config's teacher: any
            `FeedbackSource`, e.g. a `JudgeSource`; None: the config's teacher.
        progress: called as `progress(step, live)` every 100 steps, `live` holding
            eval_return, asked, inferred, sessions and sps (steps per second); None: none.

    Returns:
        The summary (summary.json): final and best evaluation return, sessions, questions
            asked, answered and inferred, `eval_curve`, wall time, ...

    Examples:
        >>> import seqrank
        >>> config = seqrank.make_config("walker_walk", scheme="root", steps=60_000)
        >>> summary = seqrank.train(config, "seqrank-out/runs/mine")  # doctest: +SKIP
        >>> config.sessions, config.max_feedback  # what the run will ask
        (5, 100)
    """
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


def offline_train(
    dataset: str | Path, out: Path | str, reward: str = "true", **settings: Any
) -> dict[str, Any]:
    """Train IQL on a fixed dataset into the directory `out`, as `seqrank offline train`
    does, and return its summary.

    A new `out` starts the run; one holding a stopped run of the same settings continues
    it (a finished one is returned as it is; other settings are refused, naming them).

    Args:
        dataset: a Minari dataset id in Minari's local folder, or a dataset folder's path
            (`seqrank dataset make` writes one).
        out: the run directory: config.json, metrics.jsonl, checkpoint.pt, summary.json.
        reward: "true" (the dataset's reward) or "learned" (`max_feedback` questions of
            `scheme` answered by `teacher`, a reward model fit to them, labels.jsonl).
        **settings: the options of `seqrank offline train` with _ for - (`steps`,
            `eval_every`, `eval_episodes`, `seed`, `scheme`, `teacher`, `max_feedback`,
            `hidden`, `expectile`, `temperature`, ...); a ValueError names a bad one.

    Returns:
        The summary (summary.json): final and best evaluation return and success rate,
            `eval_curve`, the dataset's mean episode return, the reward scaling, wall time.

    Examples:
        >>> import seqrank
        >>> seqrank.offline_train("no-such-dataset", "run", steps=100)
        Traceback (most recent call last):
        ValueError: no Minari dataset at 'no-such-dataset': ...
        >>> summary = seqrank.offline_train("door-open-v0", "run", steps=1000)  # doctest: +SKIP
    """
    from seqrank.offline.launch import open_or_start
    from seqrank.offline.settings import new_config

    config = new_config({"dataset": str(dataset), "reward": reward, **settings})
    started = open_or_start(Path(out), config)
    try:
        if started.trainer is None:
            return started.run.read_summary()
        return started.trainer.train()
    finally:
        started.run.release()


@dataclass(frozen=True)
class Run:
    """A run directory, read (`load_run`): its settings, metric rows and summary.

    Attributes:
        path: the run directory.
        config: its `TrainConfig` (config.json).
        metrics: the rows of metrics.jsonl, each with a `step` and a `kind`: train,
            feedback (a session) or eval.
        summary: summary.json (what `train` returned); None while unfinished.

    Examples:
        >>> from pathlib import Path
        >>> import seqrank
        >>> rows = [{"step": 10_000, "kind": "eval", "eval_return": 31.5}]
        >>> run = seqrank.Run(Path("mine"), seqrank.make_config(), rows, summary=None)
        >>> run.evaluations()
        [(10000, 31.5)]
    """

    path: Path
    config: TrainConfig
    metrics: list[dict[str, Any]]
    summary: dict[str, Any] | None

    def evaluations(self) -> list[tuple[int, float]]:
        """(step, mean evaluation return) of every evaluation so far."""
        return [(r["step"], r["eval_return"]) for r in self.metrics if r["kind"] == "eval"]

    def environment(self, seed: int | None = None) -> SimEnv:
        """The run's task (`make_env`), seeded with `seed` (None: the run's seed)."""
        return make_env(self.config.task, self.config.seed if seed is None else seed)

    def policy(self) -> Policy:
        """The agent of the last checkpoint, on the CPU: `policy.act(obs, True, generator)`
        gives the deterministic action."""
        from seqrank.training.agent_factory import load_policy

        return load_policy(self.path, self.environment())


def load_run(path: Path | str) -> Run:
    """Read a run directory written by `seqrank train` or `train`, finished or not.

    Args:
        path: the run directory.

    Returns:
        A `Run`: `config`, `metrics`, `summary`, `evaluations()`, `environment()` and
            `policy()`, the agent of its last checkpoint.

    Examples:
        >>> import seqrank, torch
        >>> config = seqrank.make_config("gym:Pendulum-v1", reward="true", steps=200,
        ...     seed_steps=100, eval_every=200, eval_episodes=1, hidden=32, batch=32)
        >>> _ = seqrank.train(config, "pendulum")  # a tiny run on the true reward
        >>> run = seqrank.load_run("pendulum")
        >>> run.config.task, [step for step, _ in run.evaluations()], run.summary["steps"]
        ('gym:Pendulum-v1', [200], 200)
        >>> obs, _ = run.environment().reset(seed=0)
        >>> run.policy().act(obs, True, torch.Generator()).shape
        (1,)
    """
    from seqrank.training.runs import RunDir

    run = RunDir.open(Path(path))
    summary = run.read_summary() if (run.path / "summary.json").exists() else None
    return Run(run.path, run.read_config(), run.read_metrics(), summary)
