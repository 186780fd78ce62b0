"""The reward-learning benchmark: what each scheme's answers teach the reward model, with
no RL in the way.

One cell is (pool, scheme, teacher, seed). It runs the training run's own feedback code on
the pool's training episodes: sessions of `session_questions` questions, segments cut
uniformly (a uniform episode, a uniform start within it: `pool.py`), the scripted teacher
answering (B-Pref's margin from the training episodes' mean return per step),
the scheme's transitive closure, and the reward ensemble trained (warm-started, as in a
run) on every label so far. At each question budget it scores the model on a fixed sample
of segments from held-out episodes:

- `accuracy`: the fraction of held-out segment pairs (unequal true returns) that the
  ensemble's mean predicted return orders as the true returns do;
- `spearman`: the rank correlation of predicted and true segment returns;
- `top_accuracy`, `top_recall`, `regret`: at the top of the held-out segments, where a
  policy climbing the learned reward goes (`measures.py`);
- `inferred_wrong`: the fraction of inferred labels (so far) that the true returns
  contradict (None while nothing was inferred).

Every scheme of a seed sees the same random streams (common random numbers), so their
differences are not sampling luck.

A cell's `learner` (`RewardLearner`: plain, surf, rime; docs/concepts/reward-learners.md) is how
the ensemble learns from the labels, with its default settings; SURF's unlabelled pairs
are cut from the training episodes. RIME's warm start has no place here: the benchmark
has no pre-training phase, so every learner starts from a fresh model.

Fitting controls separate what the inferred labels add from what the questions add: the
`augment` none stores the asked pairs alone (no closure); the `stop` rule counts the
fit's train accuracy over every label (`all`, a run's rule), over the asked pairs only
(`asked`), or never stops early (`never`: every one of `RewardNet.epochs`). The `order`
gives a session's new segments as drawn (`uniform`) or the same ones in the order they
were collected (`collection`, `order.py`); each row lists every session's inferred pairs
and clips so far (`session_inferred`, `session_clips`: theory's M), for `seqrank theory`.

**Windows** (`window_steps` N, `--window-steps`; off by default): pools that follow a
learning policy, one session per window of the pool's run (`windows.py`). Session k cuts
its segments from the run's episodes that ended within steps [kN, (k+1)N) (in collection
order under `collection`), with the teacher's margin from them; the model is trained on
every label so far and each budget's row is scored on the next window's episodes (window
k+1, k the last session asked), as an online run meets the data its policy collects next.
There is no return-rank split then: the future window is the held-out data; SURF's
unlabelled pairs come from the windows seen so far. Rows carry `window` (k) and
`scored_window` (k+1). The pool must hold its run's episodes from the first on, with a
window for each session and one more to score on.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np
import torch

from seqrank.episodes import EpisodeStore, Segments
from seqrank.feedback.checking import Recheck
from seqrank.feedback.closure import AugmentationStats
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.schemes import SessionRecord
from seqrank.feedback.session import FeedbackSource, SessionPlan, prepare_session, store_session
from seqrank.feedback.sources import make_source
from seqrank.feedback.teachers import parse_teacher
from seqrank.reward.learners import give_unlabelled, make_learner
from seqrank.reward.model import RewardModel, RewardTrainResult
from seqrank.rewardbench.cells import Cell
from seqrank.rewardbench.measures import annotator_seconds, heldout_measures
from seqrank.rewardbench.order import CollectionOrder
from seqrank.rewardbench.pool import Pool
from seqrank.rewardbench.windows import WindowedEpisodes, checked_windows


@dataclass(frozen=True)
class RewardNet:
    """The reward ensemble and its training (the small preset's values by default)."""

    ensemble: int = 3
    hidden: int = 256
    layers: int = 3
    lr: float = 3e-4
    epochs: int = 30
    minibatch: int = 128
    stop_accuracy: float = 0.97


@dataclass(frozen=True)
class BenchSettings:
    budgets: tuple[int, ...] = (25, 50, 100, 200)
    session_questions: int = 25
    segment_length: int = 50
    heldout_segments: int = 300
    net: RewardNet = RewardNet()
    window_steps: int | None = None  # a session per window of the pool's run (`windows.py`)
    overlap_until: int = 0  # a crowd's adaptive overlap (`seqrank.feedback.overlap`)
    closure_checks: bool = False  # second opinions on inferred pairs (`closure_checks.py`)

    def __post_init__(self) -> None:
        if not self.budgets or list(self.budgets) != sorted(set(self.budgets)):
            raise ValueError(f"budgets must rise strictly, got {list(self.budgets)}")
        if self.budgets[0] < 1 or self.session_questions < 1:
            raise ValueError("budgets and session questions must be at least 1")
        if self.window_steps is not None and self.window_steps < 1:
            raise ValueError(f"--window-steps must be at least 1, got {self.window_steps}")


class _Tally:
    def __init__(self) -> None:
        self.asked = self.answered = self.inferred = self.inferred_wrong = 0
        self.strict = self.asked_wrong = self.clips = 0
        self.seconds = self.person_seconds = 0.0
        self.reasks = 0  # a crowd's questions asked again because their owner was flagged
        self.session_inferred: list[int] = []
        self.session_clips: list[int] = []

    def add_time(self, record: SessionRecord) -> None:
        """A crowd's answering time: its sessions' lengths and everybody's time."""
        if record.crowd is not None:
            self.seconds += record.crowd.seconds
            self.person_seconds += record.crowd.person_seconds
            self.reasks += sum(o.reask for o in record.crowd.second_opinions)

    def add(self, stats_: AugmentationStats) -> None:
        self.asked += stats_.asked
        self.answered += stats_.answered
        self.strict += stats_.answered - stats_.equal
        self.asked_wrong += stats_.asked_wrong or 0
        self.inferred += stats_.inferred
        self.inferred_wrong += stats_.inferred_wrong or 0
        # the clips the session showed: the distinct segments of its questions (a pairwise
        # question shows two new ones, the others one beside the kept one)
        self.clips += stats_.unique_segments
        self.session_inferred.append(stats_.inferred)  # for `seqrank theory`'s expectation
        self.session_clips.append(stats_.unique_segments)


class _CellEpisodes(Protocol):
    """Where a cell's sessions, unlabelled pairs and measures take their episodes, by the
    session asked (`for_session`, `margin`) or the number asked so far (the others)."""

    def for_session(self, session: int) -> EpisodeStore: ...
    def margin(self, session: int) -> float: ...
    def seen(self, sessions: int) -> EpisodeStore: ...
    def heldout(self, sessions: int) -> Segments: ...
    def row_fields(self, sessions: int) -> dict[str, int]: ...


class _SplitEpisodes:
    """The pool split by return rank: every session on the training episodes, every
    budget scored on one fixed sample of the held-out ones."""

    def __init__(self, pool: Pool, collection: bool, settings: BenchSettings) -> None:
        train, held = pool.split()
        length = settings.segment_length
        self.fixed_heldout = pool.heldout_segments(held, settings.heldout_segments, length)
        self.train = pool.store(train)
        # where sessions cut their segments (SURF's unlabelled pairs stay uniform)
        self.sessions = CollectionOrder(pool, train) if collection else self.train
        self.fixed_margin = pool.margin(train, length)

    def for_session(self, session: int) -> EpisodeStore:
        return self.sessions

    def margin(self, session: int) -> float:
        return self.fixed_margin

    def seen(self, sessions: int) -> EpisodeStore:
        return self.train

    def heldout(self, sessions: int) -> Segments:
        return self.fixed_heldout

    def row_fields(self, sessions: int) -> dict[str, int]:
        return {}  # rows as they were before windows


def _cell_episodes(pool: Pool, cell: Cell, settings: BenchSettings) -> _CellEpisodes:
    collection = cell.order == "collection"
    if settings.window_steps is None:
        return _SplitEpisodes(pool, collection, settings)
    budgets, questions = settings.budgets, settings.session_questions
    windows = checked_windows(pool, settings.window_steps, budgets, questions)
    length, count = settings.segment_length, settings.heldout_segments
    return WindowedEpisodes(pool, windows, collection, length, count)


class _CellRun:
    """One cell's state between budgets: its streams, model, labels and counts."""

    def __init__(
        self, pool: Pool, cell: Cell, settings: BenchSettings, source: FeedbackSource | None
    ) -> None:
        self.pool, self.cell, self.settings = pool, cell, settings
        self.episodes = _cell_episodes(pool, cell, settings)
        self.rng = np.random.default_rng(cell.seed)
        self.generator = torch.Generator().manual_seed(cell.seed)
        torch.manual_seed(cell.seed)
        net, features = settings.net, pool.obs.shape[2] + pool.action.shape[2]
        self.model = RewardModel(
            net.ensemble, features, net.hidden, net.layers, net.lr, torch.device("cpu")
        )
        until = settings.overlap_until
        if source is None:
            checks = settings.closure_checks
            source = make_source(cell.teacher, overlap_until=until, closure_checks=checks)
        self.source = source
        self.plan = _plan(cell, settings)
        # the learner's own stream (SURF's crops and unlabelled batches): the training
        # shuffles stay those of the plain cell of the same scheme and seed
        learner_stream = torch.Generator().manual_seed(cell.seed * 10 + 4)
        self.learner = make_learner(cell.learner, learner_stream)
        self.labels, self.tally, self.session = LabelStore(cell.weighting), _Tally(), 0
        self.fitted = False  # whether the model has been fit yet (checked's second opinion)
        self.started = time.perf_counter()

    def ask_until(self, budget: int) -> None:
        """Sessions until `budget` questions are asked (or the source runs out)."""
        labels, tally = self.labels, self.tally
        while tally.asked < budget and self.source.has_session(self.session):
            questions = min(self.settings.session_questions, budget - tally.asked)
            episodes = self.episodes.for_session(self.session)
            request = prepare_session(
                self.plan, questions, episodes, self.model, self.session, self.rng,
                False, self.episodes.margin(self.session), labels.teacher_contradicted(),
                self.fitted,
            )  # fmt: skip
            request = replace(request, distrusted=labels.distrusted())  # (reask's)
            segments, record = self.source.ask_session(request)
            closure = self.cell.augment != "none"
            stored = store_session(segments, record, labels, request, closure)
            tally.add(stored.stats)
            tally.add_time(record)
            self.session += 1

    def fit_and_measure(self) -> dict[str, Any]:
        """The model trained (warm-started) on every label so far; the budget's row."""
        cell, net, tally = self.cell, self.settings.net, self.tally
        length = self.settings.segment_length
        seed = [cell.seed, 3, self.session]
        seen = self.episodes.seen(self.session)
        give_unlabelled(self.learner, seen, length, tally.asked, seed)
        asked = self.labels.asked_mask()
        fit = self.model.train(
            *self.labels.tensors(torch.device("cpu")),
            net.epochs,
            net.minibatch,
            math.inf if cell.stop == "never" else net.stop_accuracy,
            self.generator,
            sync_every_step=False,
            learner=self.learner,
            stop_pairs=asked if cell.stop == "asked" else None,
        )
        self.fitted = True
        heldout = self.episodes.heldout(self.session)
        row = _row(self.pool, cell, tally, len(self.labels), heldout, self.model, fit)
        cost = {
            "clips": tally.clips,
            "annotator_seconds": annotator_seconds(tally.clips, tally.asked, length),
            "session_inferred": list(tally.session_inferred),
            "session_clips": list(tally.session_clips),
        }
        seconds = {"seconds": time.perf_counter() - self.started}
        windows = self.episodes.row_fields(self.session)
        return {**row, **windows, **cost, **seconds, **_crowd_measures(self.labels, tally)}


def run_cell(
    pool: Pool,
    cell: Cell,
    settings: BenchSettings,
    source: FeedbackSource | None = None,
) -> list[dict[str, Any]]:
    """One row per budget reached. `source` replaces the scripted teacher (replayed labels);
    it then stops early when its sessions run out."""
    run, rows = _CellRun(pool, cell, settings, source), []
    for budget in settings.budgets:
        run.ask_until(budget)
        if not len(run.labels):
            continue  # every answer so far was a skip: nothing to learn from
        rows.append(run.fit_and_measure())
        if run.tally.asked < budget:
            break  # a replayed file ran out
    return rows


def _plan(cell: Cell, settings: BenchSettings) -> SessionPlan:
    """A cell's sessions: uniform selection, `checked`'s repeats, a crowd's chains, the
    order of its new segments."""
    recheck = Recheck() if cell.augment == "checked" else None
    crowd = len(parse_teacher(cell.teacher).members) if cell.teacher != "replay" else 0
    length = settings.segment_length
    return SessionPlan(
        cell.scheme, "uniform", 1, length, recheck=recheck, crowd=crowd, order=cell.order
    )


def _row(
    pool: Pool,
    cell: Cell,
    tally: _Tally,
    pairs: int,
    heldout: Segments,
    model: RewardModel,
    fit: RewardTrainResult,
) -> dict[str, Any]:
    wrong = tally.inferred_wrong / tally.inferred if tally.inferred else None
    return {
        "task": pool.task,
        "scheme": cell.scheme,
        "teacher": cell.teacher,
        "learner": cell.learner,
        "augment": cell.augment,
        "weighting": cell.weighting,
        "stop": cell.stop,
        "order": cell.order,
        "seed": cell.seed,
        "questions": tally.asked,
        "answered": tally.answered,
        "pairs": pairs,
        "inferred": tally.inferred,
        "inferred_wrong": wrong,
        "asked_wrong": tally.asked_wrong / tally.strict if tally.strict else None,
        **heldout_measures(model, heldout),
        "epochs": fit.epochs,  # of this budget's fit, and the learner's own measures
        **fit.learner,
    }


def _crowd_measures(labels: LabelStore, tally: _Tally) -> dict[str, Any]:
    """A crowd's: the time its people spent (sessions side by side, and added up), and
    each member's reliability estimate beside their true error rate so far (and the
    estimate with the reward model as a voter, the estimator before issue 49's)."""
    if not labels.crowd_answers:
        return {}
    members: dict[str, dict[str, Any]] = {}
    with_model = labels.reliability_with_model()
    for name, found in labels.reliability().items():
        wrong = [
            (answer == "first") != (labels.segment_returns[f] > labels.segment_returns[s])
            for f, s, answer, who, _ in labels.crowd_answers
            if who == name and answer in ("first", "second")
        ]
        members[name] = {
            "estimate": found.estimate, "low": found.low, "high": found.high,
            "answers": found.answers, "flagged": found.flagged,
            "true_error_rate": float(np.mean(wrong)) if wrong else None,
            "overlaps": found.overlaps,
        }  # fmt: skip
        if name in with_model:
            old = with_model[name]
            members[name]["with_model"] = {
                "estimate": old.estimate, "low": old.low, "high": old.high,
                "answers": old.answers, "flagged": old.flagged,
            }  # fmt: skip
    reasks = {"reasks": tally.reasks} if labels.weighting == "reask" else {}
    return {
        "crowd_minutes": tally.seconds / 60.0,
        "person_minutes": tally.person_seconds / 60.0,
        **reasks,
        "members": members,
    }
