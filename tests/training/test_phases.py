"""The training phases, choices and teacher specs on their own (no full run)."""

from __future__ import annotations

from concurrent.futures import Future

import numpy as np
import pytest
import torch

from seqrank.choices import Backbone, Selection, parse_choice
from seqrank.config import resolve_config
from seqrank.envs import make_env
from seqrank.envs.recorder import EpisodeRecorder
from seqrank.episodes import Episode, EpisodeStore
from seqrank.feedback.schemes import SchemeName, scheme_has_defender, segments_needed
from seqrank.feedback.teachers import TEACHER_PRESETS, parse_teacher
from seqrank.training.sessions import FeedbackSessions, Schedule
from seqrank.training.state import Counters

SCHEDULE = Schedule(max_feedback=30, reward_batch=10, feedback_frequency=500, episode_length=100)


class _Source:
    """A feedback source with `sessions` sessions to give."""

    def __init__(self, sessions: int):
        self.sessions = sessions

    def has_session(self, session: int) -> bool:
        return session < self.sessions


def _sessions(source: _Source, wait: bool = True, episodes: int = 1) -> FeedbackSessions:
    store = EpisodeStore(4)
    for _ in range(episodes):
        store.add(Episode(np.zeros((60, 3)), np.zeros((60, 1)), np.zeros(60)))
    return FeedbackSessions(SCHEDULE, None, source, store, None, None, wait)  # type: ignore[arg-type]


def test_the_first_session_is_due_at_once_then_every_feedback_frequency_steps():
    sessions, c = _sessions(_Source(5)), Counters(step=1200)
    assert sessions.due(c, sessions.is_open(c))  # first session, whatever the step
    c.sessions, c.asked, c.last_session_step = 1, 10, 1200
    for step, due in ((1300, False), (1699, False), (1700, True)):
        c.step = step
        assert sessions.due(c, sessions.is_open(c)) is due, step


def test_no_session_before_a_complete_episode_to_cut_segments_from():
    c = Counters(step=1200)
    assert not _sessions(_Source(5), episodes=0).due(c, True)  # a task with terminal states
    assert _sessions(_Source(5), episodes=1).due(c, True)


def test_feedback_closes_when_the_budget_or_the_source_runs_out():
    c = Counters(step=5000, sessions=3, asked=30, last_session_step=1000)
    assert not _sessions(_Source(5)).is_open(c)  # 30 of 30 questions asked
    c.asked = 20
    assert _sessions(_Source(5)).is_open(c)
    assert not _sessions(_Source(3)).is_open(c)  # a replayed file with 3 sessions
    assert not _sessions(_Source(3)).due(c, False)


def test_a_session_answered_in_the_background_blocks_the_next_until_collected():
    sessions, c = _sessions(_Source(5), wait=False), Counters(step=2000, sessions=1, asked=10)
    future: Future[object] = Future()
    sessions.pending = (object(), future)  # type: ignore[assignment]
    assert not sessions.due(c, True) and sessions.collect() is None
    future.set_result(("segments", "record"))
    answered = sessions.collect()
    assert answered is not None and answered.segments == "segments"
    assert sessions.pending is None and sessions.due(c, True)


def test_the_recorder_keeps_states_only_when_asked():
    env = make_env("dmc:cartpole_swingup", 0)
    for record_states in (True, False):
        recorder = EpisodeRecorder(record_states)
        obs, _ = env.reset(seed=1)
        for _ in range(3):
            recorder.before_step(env)
            action = np.zeros(env.act_dim, np.float32)
            next_obs, reward, *_ = env.step(action)
            recorder.add(obs, action, float(reward))
            obs = next_obs
        episode = recorder.finish(context=None)
        assert episode.obs.shape == (3, env.obs_dim) and episode.reward.shape == (3,)
        assert (episode.states is not None) is record_states
        assert recorder.finish(None).obs.shape == (0,)  # a fresh episode after finish
    env.close()


def test_warm_up_acts_at_random_then_the_agent_acts():
    from seqrank.buffer import ReplayBuffer
    from seqrank.training.collect import Collector

    class Constant:
        def act(self, obs, deterministic, generator):  # type: ignore[no-untyped-def]
            return np.full(1, 0.5, np.float32)

    env = make_env("dmc:cartpole_swingup", 0)
    replay = ReplayBuffer(50, env.obs_dim, env.act_dim, torch.device("cpu"))
    rng, generator = np.random.default_rng(0), torch.Generator()
    collector = Collector(
        env,
        Constant(),
        replay,
        EpisodeStore(2),
        False,
        5,
        rng,
        generator,
        False,
        50,  # type: ignore[arg-type]
    )
    c = Counters()
    collector.start_episode(0, c)
    for _ in range(10):
        collector.step(0, c, None)
    actions = replay.action[:10, 0]
    assert len(set(actions[:5].tolist())) == 5  # uniform random draws
    assert torch.all(actions[5:] == 0.5) and c.step == 10
    env.close()


def test_choices_are_checked_once_and_named_when_bad():
    assert parse_choice(Backbone, "mrn", "backbone") is Backbone.MRN
    with pytest.raises(ValueError, match="unknown selection 'best'; accepted: uniform"):
        parse_choice(Selection, "best", "selection")
    config = resolve_config("dmc:cartpole_swingup", "small", dict(scheme="root"))
    assert config.scheme is SchemeName.ROOT and config.scheme == "root"
    with pytest.raises(ValueError, match="unknown scheme 'tree'; accepted: pairwise, seq"):
        resolve_config("dmc:cartpole_swingup", "small", dict(scheme="tree"))


def test_a_scheme_knows_whether_it_has_a_defender():
    assert not SchemeName.PAIRWISE.has_defender
    assert all(SchemeName(s).has_defender for s in ("sequential", "root", "ranked"))
    assert segments_needed("pairwise", 10) == 20 and segments_needed("root", 10) == 11
    with pytest.raises(ValueError, match="unknown scheme"):
        scheme_has_defender("tree")


def test_teacher_specs_reach_every_b_pref_knob():
    assert parse_teacher("mistake").scripted == TEACHER_PRESETS["mistake"]
    spec = parse_teacher("mistake,eps_mistake=0.2,gamma=0.95")
    assert spec.scripted is not None and spec.short_name == "custom"
    assert (spec.scripted.eps_mistake, spec.scripted.gamma) == (0.2, 0.95)
    knobs = parse_teacher("beta=1,eps_skip=0.1,eps_equal=0.05,tie_rule=random").scripted
    assert knobs is not None and (knobs.beta, knobs.tie_rule) == (1.0, "random")
    assert parse_teacher("replay:labels.jsonl").replay_file == "labels.jsonl"
    assert parse_teacher("human").kind == "human"


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("perfect", "unknown teacher 'perfect'; accepted: oracle, mistake"),
        ("oracle,temperature=2", "unknown knob 'temperature'; knobs: beta, gamma"),
        ("oracle,beta=", "'beta=' is not knob=value"),
        ("beta=high", "beta must be a number, got 'high'"),
        ("gamma=1.5", "gamma must be in"),
        ("replay:", "needs a file"),
    ],
)
def test_bad_teacher_specs_are_named(value, message):
    with pytest.raises(ValueError, match=message):
        parse_teacher(value)
    with pytest.raises(ValueError, match=message):
        resolve_config("dmc:cartpole_swingup", "small", dict(teacher=value))
