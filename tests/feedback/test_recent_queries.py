"""QPA's policy-aligned queries: with `query_episodes` N every candidate segment of a session
comes from the last N stored episodes, for every scheme and selection; without it, from all
of them."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from seqrank.config import resolve_config
from seqrank.episodes import Episode, EpisodeStore
from seqrank.feedback.schemes import SchemeName
from seqrank.feedback.session import ScriptedSource, SessionPlan, prepare_session
from seqrank.feedback.teachers import ScriptedTeacher, parse_teacher
from seqrank.reward.model import RewardModel

OBS, ACT, LENGTH = 3, 2, 60


def numbered_store(episodes: int, keep: int) -> EpisodeStore:
    """Episodes whose every feature is their number (0, 1, ...), rewards random."""
    store, rng = EpisodeStore(keep), np.random.default_rng(0)
    for k in range(episodes):
        store.add(
            Episode(
                np.full((LENGTH, OBS), k, np.float32),
                np.full((LENGTH, ACT), k, np.float32),
                rng.normal(size=LENGTH),
            )
        )
    return store


def session_from(store: EpisodeStore, scheme: str, selection: str, query_episodes: int):
    plan = SessionPlan(scheme, selection, 4, 10, query_episodes=query_episodes)
    model = RewardModel(3, OBS + ACT, 8, 2, 1e-3, torch.device("cpu"))
    rng = np.random.default_rng(1)
    request = prepare_session(plan, 12, store, model, 1, rng, informative=True, margin=0.0)
    teacher = ScriptedTeacher(parse_teacher("oracle").scripted)  # type: ignore[arg-type]
    segments, record = ScriptedSource(teacher).ask_session(request)
    return request, segments, record


def episodes_of(features: np.ndarray) -> set[int]:
    assert (features == features[:, :1, :1]).all()  # each segment from one episode
    return set(features[:, 0, 0].astype(int).tolist())


@pytest.mark.parametrize("selection", ["uniform", "disagreement", "entropy"])
@pytest.mark.parametrize("scheme", [s.value for s in SchemeName])
def test_every_candidate_comes_from_the_last_n_episodes(scheme, selection):
    store = numbered_store(episodes=30, keep=20)  # holds episodes 10 to 29
    request, segments, record = session_from(store, scheme, selection, query_episodes=4)
    assert episodes_of(request.segments.features) == {26, 27, 28, 29}
    assert request.episodes == (26, 29)
    asked = segments.features[list(record.segments)]
    assert record.answers and episodes_of(asked) <= {26, 27, 28, 29}


@pytest.mark.parametrize("scheme", [s.value for s in SchemeName])
def test_without_the_option_candidates_come_from_every_kept_episode(scheme):
    store = numbered_store(episodes=30, keep=20)
    request, _, _ = session_from(store, scheme, "disagreement", query_episodes=0)
    seen = episodes_of(request.segments.features)
    assert seen <= set(range(10, 30)) and min(seen) < 26
    assert request.episodes is None  # (and the feedback row logs no window)


def test_all_kept_episodes_draw_what_the_store_always_drew():
    store, rng_a, rng_b = numbered_store(12, 8), np.random.default_rng(3), np.random.default_rng(3)
    everything = store.sample_segments(50, 10, rng_a)
    explicit = store.sample_segments(50, 10, rng_b, last=8)
    assert np.array_equal(everything.features, explicit.features)


def test_the_window_counts_episodes_over_the_run_and_survives_a_checkpoint():
    store = numbered_store(12, 5)
    assert store.window() == (7, 11) and store.window(2) == (10, 11)
    assert store.window(50) == (7, 11)  # no more than the store holds
    restored = EpisodeStore(5)
    restored.load_state_dict(store.state_dict())
    assert restored.window(3) == (9, 11)


def test_query_episodes_above_the_kept_episodes_is_refused():
    with pytest.raises(ValueError, match="query_episodes 30 exceeds episodes_kept 20"):
        resolve_config("dmc:cartpole_swingup", "small", {"episodes_kept": 20, "query_episodes": 30})
    config = resolve_config("dmc:cartpole_swingup", "small", {"query_episodes": 10})
    assert config.query_episodes == 10 and config.hybrid_replay == 0
