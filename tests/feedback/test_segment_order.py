"""`segment_order` (issue 46, item 3): a run's session gives its scheme the segments it
drew, as drawn (uniform) or in the order they were collected (collection): the same
segments, from the same draws, each episode's before the next one's."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import seqrank
from seqrank.episodes import Episode, EpisodeStore
from seqrank.feedback.schemes import in_order_choice
from seqrank.feedback.session import SessionPlan, prepare_session
from seqrank.feedback.sources import make_source
from seqrank.reward.model import RewardModel
from seqrank.training.feedback_parts import session_plan

LENGTH = 10


def store(episodes: int = 8, steps: int = 40) -> EpisodeStore:
    """Observation 0 is the step's place in the run: episode + step / 1000."""
    kept = EpisodeStore(episodes)
    for e in range(episodes):
        obs = np.zeros((steps, 2), np.float32)
        obs[:, 0] = e + np.arange(steps) / 1000
        obs[:, 1] = np.random.default_rng(e).normal(size=steps)
        kept.add(Episode(obs, np.zeros((steps, 1), np.float32), obs[:, 1].astype(np.float64)))
    return kept


def when(features: np.ndarray) -> list[float]:
    return [round(float(f[0, 0]), 3) for f in features]


def request(order: str, scheme: str = "root", seed: int = 4, crowd: int = 0):
    plan = SessionPlan(scheme, "uniform", 1, LENGTH, crowd=crowd, order=order)
    model = RewardModel(1, 3, 8, 1, 1e-3, torch.device("cpu"))
    rng = np.random.default_rng(seed)
    return prepare_session(plan, 12, store(), model, 0, rng, False, 1.0)


def test_collection_order_gives_the_drawn_segments_as_collected():
    uniform, ordered = request("uniform"), request("collection")
    drawn, collected = when(uniform.segments.features), when(ordered.segments.features)
    assert collected == sorted(collected) and drawn != sorted(drawn)
    assert sorted(drawn) == collected  # the same segments: the same draws
    assert ordered.chooser is in_order_choice and uniform.chooser is not in_order_choice
    assert ordered.in_order and not uniform.in_order


@pytest.mark.parametrize("scheme", ["pairwise", "sequential", "root", "ranked"])
def test_each_scheme_meets_the_segments_in_the_order_collected(scheme):
    segments, record = make_source("oracle").ask_session(request("collection", scheme))
    met = list(dict.fromkeys(s for a in record.answers for s in (a.first, a.second)))
    times = when(segments.features[met])
    assert times == sorted(times)


def test_a_run_records_and_resolves_the_order():
    config = seqrank.make_config("walker_walk", scheme="root", segment_order="collection")
    assert config.as_dict()["segment_order"] == "collection"
    assert session_plan(config).order == "collection"
    assert session_plan(seqrank.make_config("walker_walk")).order == "uniform"


def test_a_team_in_collection_order_has_each_member_span_the_session():
    """Contiguous slices of a pool in collection order would give the first member the
    oldest segments and the last the newest, every session: dealt, each spans it."""
    from seqrank.feedback.crowd import share_session

    sliced, reserve = share_session("root", 30, 40, 3)
    dealt, same_reserve = share_session("root", 30, 40, 3, dealt=True)
    assert reserve == same_reserve
    assert [len(c.pool_ids) for c in dealt] == [len(c.pool_ids) for c in sliced]
    assert sorted(i for c in dealt for i in c.pool_ids) == sorted(
        i for c in sliced for i in c.pool_ids
    )
    for chain in dealt:
        assert list(chain.pool_ids) == sorted(chain.pool_ids)
        usable = sum(len(c.pool_ids) for c in dealt)
        assert chain.pool_ids[0] < 3 and chain.pool_ids[-1] > 0.75 * usable  # early to late
    team = make_source("crowd:oracle+oracle+oracle")
    _, record = team.ask_session(request("collection", crowd=3))
    assert record.crowd is not None
    places = {}
    for answer, who in zip(record.answers, record.crowd.answered_by, strict=True):
        places.setdefault(who, []).extend([answer.first, answer.second])
    assert all(min(p) < 3 for p in places.values())  # every member meets early segments
