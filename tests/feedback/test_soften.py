"""Crowd weighting `soften` (issue 49, item 3): a flagged member's labels train as the
probability that they are right, left out when they are right half the time or less;
everybody else's as answered; nobody flagged, exactly as answered."""

from __future__ import annotations

import numpy as np

from seqrank.episodes import Segments
from seqrank.feedback.crowd import CrowdSource
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.reliability import soft_label
from seqrank.feedback.schemes import segments_needed, uniform_choice
from seqrank.feedback.session import SessionRequest, store_session
from seqrank.feedback.teachers import parse_teacher
from seqrank.simulate import synthetic_segments

GOOD = "crowd:oracle+oracle+oracle,name=third"
NOISY = "crowd:oracle+oracle+mistake,eps_mistake=0.3,name=noisy"
WRONG = "crowd:oracle+oracle+mistake,eps_mistake=1.0,name=bad"


def crowd_request(session: int, rng: np.random.Generator, questions: int = 30) -> SessionRequest:
    """A sequential session for three chains on a fresh synthetic pool."""
    rewards = synthetic_segments(segments_needed("sequential", questions, 3), 20, rng)
    pool = Segments(rewards[:, :, None], rewards, [None] * len(rewards), [None] * len(rewards))
    margin = float(rewards.sum(axis=1).mean())
    return SessionRequest(
        "sequential", questions, session, pool, uniform_choice, rng, margin, chains=3
    )


def stores(crowd: str, sessions: int = 3) -> dict[str, LabelStore]:
    """The same crowd's sessions (the same answers) stored under each weighting."""
    found = {}
    for weighting in ("none", "drop", "soften"):
        source = CrowdSource(parse_teacher(crowd).members, overlap=0.1, overlap_until=30)
        labels, rng = LabelStore(weighting), np.random.default_rng(5)
        for session in range(sessions):
            request = crowd_request(session, rng)
            _, record = source.ask_session(request)
            store_session(request.segments, record, labels, request)
        found[weighting] = labels
    return found


def test_nobody_flagged_soften_trains_the_answers_as_given():
    found = stores(GOOD)
    assert not any(r.flagged for r in found["soften"].reliability().values())
    assert found["soften"].kept() == found["none"].kept()
    assert found["soften"].training_labels() == found["none"].training_labels()


def test_a_member_right_seven_times_in_ten_trains_softened_and_the_others_as_given():
    found = stores(NOISY)
    soften, none = found["soften"], found["none"]
    noisy = soften.reliability()["noisy"]
    assert noisy.flagged and 0.55 < noisy.estimate < 0.8, noisy.estimate
    assert all(soften.kept())  # nothing left out: their answers still say something
    for label, given, who in zip(
        soften.training_labels(), none.training_labels(), soften.annotator, strict=True
    ):
        assert label == (soft_label(given, noisy) if who == "noisy" else given)
    assert any(label not in (0.0, 0.5, 1.0) for label in soften.training_labels())


def test_a_member_always_wrong_is_left_out_as_drop_leaves_them_out():
    found = stores(WRONG)
    soften, drop = found["soften"], found["drop"]
    bad = soften.reliability()["bad"]
    assert bad.flagged and bad.estimate <= 0.5
    assert soften.kept() == drop.kept() and not all(soften.kept())
    kept = [k for k in soften.kept() if k]
    assert len(kept) < len(soften)
