"""Feedback sessions: when one is due, asking it, and (for a person, with
`wait_for_feedback=False`) answering sessions after the first in the background while
training goes on; their labels count once the session is complete."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from seqrank.episodes import EpisodeStore, Segments
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.schemes import SessionRecord
from seqrank.feedback.session import FeedbackSource, SessionPlan, SessionRequest, prepare_session
from seqrank.reward.model import RewardModel
from seqrank.training.state import Counters


@dataclass(frozen=True)
class Schedule:
    max_feedback: int  # questions in the whole run
    reward_batch: int  # questions per session
    feedback_frequency: int  # steps between sessions
    episode_length: int


@dataclass(frozen=True)
class AnsweredSession:
    request: SessionRequest
    segments: Segments  # the pool the record's segment ids index into
    record: SessionRecord


class FeedbackSessions:
    def __init__(
        self,
        schedule: Schedule,
        plan: SessionPlan,
        source: FeedbackSource,
        episodes: EpisodeStore,
        reward_model: RewardModel,
        rng: np.random.Generator,
        wait_for_feedback: bool,
        labels: LabelStore | None = None,  # the run's: has the teacher contradicted themselves?
    ):
        self.schedule, self.plan, self.source = schedule, plan, source
        self.labels = labels
        self.episodes, self.reward_model, self.rng = episodes, reward_model, rng
        self.wait_for_feedback = wait_for_feedback
        # called with the session's index before its segments are cut (fine-tuning's parts)
        self.before_session: Callable[[int], None] | None = None
        self.pending: tuple[SessionRequest, Future[tuple[Segments, SessionRecord]]] | None = None
        self._background: ThreadPoolExecutor | None = None

    def is_open(self, c: Counters) -> bool:
        """Budget left, and a source that can still give a session."""
        return c.asked < self.schedule.max_feedback and self.source.has_session(c.sessions)

    def due(self, c: Counters, is_open: bool) -> bool:
        """The first session at once; later ones every `feedback_frequency` steps."""
        if self.pending is not None or len(self.episodes) == 0:
            return False  # (segments are cut from complete episodes)
        since = c.step - c.last_session_step
        return c.sessions == 0 or (is_open and since >= self.schedule.feedback_frequency)

    def collect(self) -> AnsweredSession | None:
        """A session answered in the background since the last call, if any."""
        if self.pending is None or not self.pending[1].done():
            return None
        request, future = self.pending
        self.pending = None
        return AnsweredSession(request, *future.result())

    def ask(self, c: Counters) -> AnsweredSession | None:
        """Ask the next session: its answers, or None while it is answered in the
        background (the first session is always waited for)."""
        first = c.sessions == 0
        if self.before_session is not None:
            self.before_session(c.sessions)
        request = self._request(c, first)
        if first or self.wait_for_feedback:
            return AnsweredSession(request, *self.source.ask_session(request))
        if self._background is None:
            self._background = ThreadPoolExecutor(1, thread_name_prefix="feedback")
        self.pending = (request, self._background.submit(self.source.ask_session, request))
        c.last_session_step = c.step
        return None

    def _request(self, c: Counters, first: bool) -> SessionRequest:
        s = self.schedule
        questions = min(s.reward_batch, s.max_feedback - c.asked)
        # B-Pref's margin: the mean return of recent episodes, scaled to a segment
        recent = float(self.episodes.recent_returns(10).mean())
        margin = recent * self.plan.segment_length / s.episode_length
        request = prepare_session(
            self.plan,
            questions,
            self.episodes,
            self.reward_model,
            c.sessions,
            self.rng,
            informative=not first,
            margin=margin,
            contradicted=self.labels is not None and self.labels.teacher_contradicted(),
            model_fit=not first,
        )
        if self.labels is None:
            return request
        # (reask: whose questions the crowd asks again of someone else; nobody otherwise)
        return replace(request, distrusted=self.labels.distrusted())
