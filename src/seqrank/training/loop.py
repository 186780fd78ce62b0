"""The PEBBLE / MRN training loop (SPEC sections 1 and 7), phase by phase.

Each step: act and store (random actions during the warm-up); then, by step (for the
learned reward; the baselines of `RewardSignal` skip what they do not need),
- warm-up (`seed_steps`): nothing to learn yet;
- unsupervised pre-training (until `seed_steps + unsup_steps`): the agent learns from the
  state-entropy reward;
- afterwards: a feedback session when one is due (the first at once, then every
  `feedback_frequency` steps while budget remains), answered by the run's source and
  augmented by the scheme's closure; reward training on every label so far; relabelling
  of the replay buffer; after the first session only, the critic reset; and the agent
  update of the backbone (PEBBLE: the agent's own; MRN: with a meta reward step);
- evaluation every `eval_every` steps, a `train` row every 1 000 steps, and a checkpoint
  at the end of an episode once `checkpoint_every` steps have passed (and at the last step;
  when a stop is requested, at the next episode end, before `RunStopped` is raised).

Every episode and evaluation episode is seeded from the run seed and its index, and all
other randomness comes from one numpy and one torch generator that are checkpointed, so a
resumed run reproduces an uninterrupted one exactly on the same machine.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from seqrank.choices import RewardSignal
from seqrank.config import TrainConfig
from seqrank.training import metrics
from seqrank.training.backbones import AgentUpdate
from seqrank.training.checkpoint import Checkpointed
from seqrank.training.critic_reset import reset_critic
from seqrank.training.feedback_phase import feedback_step, learn_from_session
from seqrank.training.runtime import Runtime
from seqrank.training.sessions import AnsweredSession, FeedbackSessions
from seqrank.training.state import episode_seed

Progress = Callable[[int, dict[str, Any]], None]
PhaseTimer = Callable[[str], contextlib.AbstractContextManager[None]]


class Run(Checkpointed, Protocol):
    """What the loop drives: a run's parts (a `Trainer` assembles them)."""

    config: TrainConfig
    runtime: Runtime
    sessions: FeedbackSessions
    update: AgentUpdate
    progress: Progress | None
    phase_timer: PhaseTimer
    stop_requested: threading.Event

    def save_checkpoint(self) -> None: ...


class RunStopped(Exception):
    """Training stopped on request (`Run.stop_requested`) at an episode end, after a
    checkpoint of that step: the run continues from there with `--resume`."""

    def __init__(self, step: int):
        super().__init__(f"stopped at step {step}")
        self.step = step


def run_loop(t: Run) -> dict[str, Any]:
    config, c = t.config, t.counters
    t.collector.start_episode(config.seed, c)
    tick = time.perf_counter()
    while c.step < config.steps:
        episode_over = t.collector.step(config.seed, c, t.reward.reward_fn(_reward_ready(t)))
        learn(t)
        if c.step % metrics.TRAIN_LOG_EVERY == 0 and t.agent.last_metrics:
            stats_std = t.pretraining.stats.std
            t.run_dir.append_metrics(
                metrics.train_row(c, _phase(t), t.agent.last_metrics, stats_std)
            )
        if c.step % config.eval_every == 0 or c.step == config.steps:
            with t.phase_timer("evaluation"):
                evaluate(t)
        for scored in t.evaluations.due(c.step, everything=c.step == config.steps):
            t.run_dir.append_metrics(metrics.eval_row(c, scored.step, scored.score, scored.context))
        now = time.perf_counter()
        c.train_seconds, tick = c.train_seconds + now - tick, now
        if t.progress is not None and (c.step % 100 == 0 or c.step == config.steps):
            t.progress(c.step, metrics.live(c))
        if episode_over and c.step - c.last_checkpoint_step >= config.checkpoint_every:
            t.save_checkpoint()
        if episode_over and c.step < config.steps and t.stop_requested.is_set():
            if c.last_checkpoint_step != c.step:
                t.save_checkpoint()
            raise RunStopped(c.step)
    if c.last_checkpoint_step != c.step:  # a finished run always leaves its final policy
        t.save_checkpoint()
    summary = metrics.summary(config, c, t.run_dir.read_metrics(), t.runtime)
    t.run_dir.write_summary(summary)
    return summary


def _phase(t: Run) -> str:
    """The `phase` of a `train` row: pretrain, preference, true-reward or no-feedback."""
    if t.config.reward is not RewardSignal.LEARNED:
        first = t.config.first_session_step
        pretraining = t.config.reward is RewardSignal.NONE and t.counters.step < first
        return "pretrain" if pretraining else t.config.reward.method
    return "pretrain" if t.counters.step < t.config.first_session_step else "preference"


def _reward_ready(t: Run) -> bool:
    """Whether new transitions get the reward model's reward: after the first session, or
    from the end of pre-training for the no-feedback baseline (the true-reward baseline
    trains on the true reward column and never needs it)."""
    config, c = t.config, t.counters
    if config.reward is RewardSignal.NONE:
        return c.step >= config.first_session_step
    return config.reward is RewardSignal.LEARNED and c.sessions > 0


def learn(t: Run) -> None:
    """What the agent and the reward model learn at this step."""
    config, c = t.config, t.counters
    if c.step < config.seed_steps:  # warm-up: random actions only
        return
    if config.reward is RewardSignal.TRUE:  # the baseline: no pre-training, no feedback
        t.update(c.step, False)
        return
    if c.step < config.first_session_step:
        t.pretraining.update()
        return
    if config.reward is RewardSignal.NONE:
        if c.step == config.first_session_step:  # what the first session would do, unlearned
            t.reward.relabel()
            reset_critic(t.agent, t.replay, config.updates_after_reset, config.batch, t.generator)
        t.update(c.step, False)
        return
    feedback_open = feedback_step(t.sessions, c, lambda answered: finish_session(t, answered))
    t.update(c.step, feedback_open)


def finish_session(t: Run, answered: AnsweredSession | None) -> None:
    """Augment and store the answers, train the reward, relabel, and after the first
    session reset the critic (nothing while a session is still being answered)."""
    if answered is None:
        return
    with t.phase_timer("feedback_session"):
        _learn_from_session(t, answered)


def _learn_from_session(t: Run, answered: AnsweredSession) -> None:
    config = t.config

    def reset() -> None:
        reset_critic(t.agent, t.replay, config.updates_after_reset, config.batch, t.generator)

    row = learn_from_session(answered, t.labels, t.counters, t.reward, config.seed, reset)
    t.run_dir.append_metrics(row)


def evaluate(t: Run) -> None:
    """Submit an evaluation of the current policy: scored now on the reference path, by
    the evaluation process (and logged `eval_every / 2` steps later) on the fast path."""
    config, c = t.config, t.counters
    seeds = [episode_seed(config.seed, 1, c.evaluations, i) for i in range(config.eval_episodes)]
    c.evaluations += 1
    context = metrics.eval_context(c, t.agent.eval_metrics())
    t.evaluations.submit(c.step, c.step + max(config.eval_every // 2, 1), context, seeds)
