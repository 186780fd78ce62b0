"""A run's feedback phase, shared by seqrank's loop and other agents' (`seqrank.sb3`):
ask a session when one is due, then learn from its answers (augment and store, fit the
reward, relabel the stored transitions, reset the critic after the first session)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from seqrank.feedback.labels import LabelStore
from seqrank.feedback.session import store_session
from seqrank.training import metrics
from seqrank.training.reward_phase import RewardLearning
from seqrank.training.sessions import AnsweredSession, FeedbackSessions
from seqrank.training.state import Counters

Finish = Callable[[AnsweredSession | None], None]


def feedback_step(sessions: FeedbackSessions, c: Counters, finish: Finish) -> bool:
    """Finish a session answered in the background, ask the next one when it is due;
    returns whether feedback is still open (budget left)."""
    finish(sessions.collect())
    feedback_open = sessions.is_open(c)
    if sessions.due(c, feedback_open):
        finish(sessions.ask(c))
    return feedback_open


def learn_from_session(
    answered: AnsweredSession,
    labels: LabelStore,
    c: Counters,
    reward: RewardLearning,
    run_seed: int,
    reset_critic: Callable[[], None],
) -> dict[str, Any]:
    """Everything a session's answers change; returns its `feedback` metrics row."""
    request = answered.request
    outcome = store_session(answered.segments, answered.record, labels, request)
    metrics.count_session(c, outcome.stats)
    result = reward.train(run_seed, c.sessions, c.asked)
    reward.relabel()
    if request.session == 0:
        reset_critic()
    quality = reward.quality(run_seed, c.sessions)
    row = metrics.feedback_row(c, outcome.stats, result, len(labels), quality, request.episodes)
    if answered.record.crowd is not None:
        row.update(metrics.crowd_fields(answered.record.crowd, labels.reliability()))
    return row
