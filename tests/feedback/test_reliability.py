"""Annotators' reliability (`seqrank.feedback.reliability`: one-coin Dawid-Skene with the
reward model as one more voter) and the soft labels it gives reward training."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from seqrank.episodes import Segments
from seqrank.feedback.checking import Recheck
from seqrank.feedback.crowd import CrowdSource
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.reliability import (
    FLAG_AFTER,
    MODEL,
    Evidence,
    Reliability,
    estimate_reliability,
    evidence_rows,
    soft_label,
)
from seqrank.feedback.schemes import segments_needed, uniform_choice
from seqrank.feedback.session import SessionRequest, store_session
from seqrank.feedback.teachers import parse_teacher
from seqrank.simulate import run_crowd_sessions, synthetic_segments


def said(pair: tuple[int, int], who: str, first: bool, model: float | None = None) -> Evidence:
    return Evidence(pair, who, first, model)


def known(estimate: float, answers: int = 10) -> Reliability:
    return Reliability("x", estimate, 0.0, 1.0, answers, 0, None)


# --- the estimate, by hand ---------------------------------------------------------------


def test_answering_one_pair_both_ways_lowers_the_estimate():
    """a answers a pair twice alike, b one pair both ways: b is right once of twice whatever
    the truth, (1 + 1) / (2 + 2) = 1/2; a is right twice of twice, about (2 + 1) / (2 + 2)."""
    estimates = estimate_reliability(
        [
            said((0, 1), "a", True),
            said((0, 1), "a", True),
            said((2, 3), "b", True),
            said((2, 3), "b", False),
        ]
    )
    assert estimates["b"].estimate == pytest.approx(0.5)
    assert estimates["a"].estimate == pytest.approx(0.75, abs=1e-3)
    assert estimates["a"].answers == estimates["b"].answers == 2
    # the same person, with and without a contradiction besides
    steady = [said((k, k + 1), "c", True) for k in range(0, 20, 2) for _ in range(2)]
    torn = [*steady, said((50, 51), "c", True), said((50, 51), "c", False)]
    assert estimate_reliability(torn)["c"].estimate < estimate_reliability(steady)["c"].estimate


def test_the_model_vote_alone_informs_when_nobody_overlaps():
    """x and y never answer the same pair; the model agrees with x's ten answers and with
    none of y's: the model and x vouch for each other, y is found wrong."""
    x = [said((k, 100 + k), "x", True, 0.9) for k in range(10)]
    y = [said((k, 100 + k), "y", True, 0.2) for k in range(10, 20)]
    estimates = estimate_reliability(x + y)
    assert estimates["x"].answers == estimates["y"].answers == 10
    assert estimates["x"].estimate > 0.8
    assert estimates["y"].estimate < 0.2
    # the model's own reliability rests on pairs two people answered: none here, its prior
    assert estimates[MODEL].answers == 0
    # without the model nothing speaks for either: no answers counted, the prior's mean
    blind = estimate_reliability([said(e.pair, e.annotator, e.said_first) for e in x + y])
    for name in ("x", "y"):
        assert blind[name].answers == 0 and blind[name].estimate == 0.5
        assert (blind[name].low, blind[name].high) == pytest.approx((0.025, 0.975))
    assert MODEL not in blind


def test_pairs_with_a_single_opinion_are_left_out():
    shared = [
        *(said((k, k + 10), "x", True) for k in range(3)),
        said((0, 10), "y", True),
        said((1, 11), "y", True),
        said((2, 12), "y", False),
    ]
    alone = [said((k, k + 10), "x", k % 2 == 0) for k in range(20, 25)]  # x only, right or not
    alone += [said((40, 41), "y", True)]
    with_alone, without = estimate_reliability(shared + alone), estimate_reliability(shared)
    assert with_alone["x"].answers == 3 and with_alone["y"].answers == 3
    assert with_alone["x"].overlaps == 3 and with_alone["x"].agreement == pytest.approx(2 / 3)
    for name in ("x", "y"):
        assert with_alone[name] == without[name]


def test_an_answer_agrees_only_when_it_agrees_with_every_other_answer_to_its_pair():
    evidence = [said((0, 1), "x", True), said((0, 1), "y", True), said((0, 1), "z", False)]
    evidence += [said((2, 3), "x", True), said((2, 3), "y", True)]
    estimates = estimate_reliability(evidence)
    assert estimates["x"].overlaps == 2 and estimates["x"].agreement == pytest.approx(1 / 2)
    assert estimates["z"].overlaps == 1 and estimates["z"].agreement == 0.0


def test_two_people_and_only_their_overlaps_cannot_be_told_apart():
    """Two annotators on the same pairs, and no model: agreeing pairs count for both,
    disagreeing ones against both alike (a third person or the model breaks the tie)."""
    evidence = []
    for k in range(20):
        evidence += [said((k, k + 50), "x", True), said((k, k + 50), "y", k % 4 != 0)]
    estimates = estimate_reliability(evidence)
    assert estimates["x"].estimate == pytest.approx(estimates["y"].estimate)
    assert estimates["x"].agreement == estimates["y"].agreement == pytest.approx(15 / 20)


def test_an_annotator_is_flagged_only_once_the_estimate_rests_on_enough_answers():
    def contradicting(pairs: int) -> Reliability:
        evidence = [said((k, k + 1), "z", first) for k in range(pairs) for first in (True, False)]
        return estimate_reliability(evidence)["z"]

    few, many = contradicting(FLAG_AFTER // 2 - 1), contradicting(FLAG_AFTER // 2)
    assert few.estimate == pytest.approx(0.5) and not few.flagged
    assert many.estimate == pytest.approx(0.5) and many.flagged
    assert not estimate_reliability([said((0, 1), "a", True)] * FLAG_AFTER)["a"].flagged


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.integers(0, 6),  # pair
            st.sampled_from(["a", "b", "c"]),
            st.booleans(),
            st.one_of(st.none(), st.floats(0.01, 0.99)),
        ),
        min_size=1,
        max_size=40,
    )
)
def test_the_interval_contains_the_estimate(rows):
    evidence = [said((pair, pair + 10), who, first, model) for pair, who, first, model in rows]
    for r in estimate_reliability(evidence).values():
        assert 0.0 <= r.low <= r.estimate <= r.high <= 1.0
        assert 0 <= r.overlaps <= r.answers


def test_evidence_rows_key_a_pair_alike_both_ways_round_and_drop_equal_and_skip():
    rows = [
        (3, 7, "first", "a", 0.9),
        (7, 3, "first", "b", 0.2),  # the same pair asked the other way round
        (3, 7, "equal", "a", None),
        (3, 7, "skip", "b", None),
        (8, 2, "second", "c", None),
    ]
    evidence = evidence_rows(rows)
    assert [(e.pair, e.annotator, e.said_first) for e in evidence] == [
        ((3, 7), "a", True),
        ((3, 7), "b", False),
        ((2, 8), "c", True),
    ]
    assert evidence[0].model_first == 0.9
    assert evidence[1].model_first == pytest.approx(0.8)
    assert evidence[2].model_first is None


# --- soft labels ---------------------------------------------------------------------------


@pytest.mark.parametrize("p", [0.5, 0.7, 0.93, 1.0])
def test_a_soft_label_is_the_probability_that_the_answer_is_right(p):
    assert soft_label(1.0, known(p)) == pytest.approx(p)
    assert soft_label(0.0, known(p)) == pytest.approx(1 - p)
    assert soft_label(0.5, known(p)) == 0.5


@pytest.mark.parametrize("p", [0.0, 0.2, 0.49])
def test_a_reliability_below_one_half_counts_as_no_information_never_a_flip(p):
    assert soft_label(1.0, known(p)) == 0.5
    assert soft_label(0.0, known(p)) == 0.5


def test_an_annotator_nothing_is_known_of_keeps_the_label():
    for label in (0.0, 0.5, 1.0):
        assert soft_label(label, known(0.9, answers=0)) == label
        assert soft_label(label, known(0.2, answers=0)) == label


# --- the label store -----------------------------------------------------------------------


def crowd_store(weighting: str, overlap: float, with_model: bool, sessions: int = 4) -> LabelStore:
    """A store of a three-person crowd's sequential sessions (a perfect model's opinion of
    each pool when `with_model`)."""
    source = CrowdSource(
        parse_teacher("crowd:oracle+mistake,eps_mistake=0.3+noisy").members, overlap
    )
    labels, rng = LabelStore(weighting), np.random.default_rng(7)
    questions = 15
    for session in range(sessions):
        rewards = synthetic_segments(segments_needed("sequential", questions, 3), 20, rng)
        pool = Segments(rewards[:, :, None], rewards, [None] * len(rewards), [None] * len(rewards))
        returns = rewards.sum(axis=1)
        model = tuple(returns.tolist()) if with_model else None
        request = SessionRequest(
            "sequential", questions, session, pool, uniform_choice, rng, float(returns.mean()),
            model_returns=model, chains=3,
        )  # fmt: skip
        _, record = source.ask_session(request)
        store_session(pool, record, labels, request)
    return labels


def test_unweighted_training_labels_are_the_labels():
    labels = crowd_store("none", overlap=0.5, with_model=True)
    assert labels.reliability()  # there is something it could weight by
    assert labels.training_labels() == labels.labels


def test_weighted_training_labels_are_each_annotators_probability_of_being_right():
    labels = crowd_store("reliability", overlap=0.5, with_model=True)
    trust = labels.reliability()
    assert set(trust) == {"oracle", "mistake", "noisy"}  # the model's own left out
    assert trust["oracle"].estimate > trust["mistake"].estimate
    weighted = labels.training_labels()
    assert len(weighted) == len(labels.labels)
    for label, name, soft in zip(labels.labels, labels.annotator, weighted, strict=True):
        p = max(trust[name].estimate, 0.5)
        assert soft == pytest.approx({1.0: p, 0.0: 1 - p, 0.5: 0.5}[label])
    assert sum(w != lab for w, lab in zip(weighted, labels.labels, strict=True)) > 0
    fitted = labels.tensors(torch.device("cpu"))[3]
    assert fitted.tolist() == pytest.approx(weighted, abs=1e-6)


def test_weighting_leaves_the_labels_of_annotators_nothing_is_known_of():
    """No overlap and no model: every pair has one opinion, nobody's reliability rests on
    any answer, and the weighted labels are the answers."""
    labels = crowd_store("reliability", overlap=0.0, with_model=False)
    assert all(r.answers == 0 for r in labels.reliability().values())
    assert labels.training_labels() == labels.labels
    assert set(labels.labels) <= {0.0, 0.5, 1.0}


def test_one_teachers_labels_are_never_weighted():
    labels = LabelStore("reliability")
    labels.labels, labels.annotator = [1.0, 0.0, 0.5], ["", "", ""]
    labels.first, labels.second = [0, 1, 2], [1, 2, 0]
    assert labels.reliability() == {}
    assert labels.training_labels() == [1.0, 0.0, 0.5]


# --- learning: the estimate tells a careful member from a careless one -------------------
# measured over 20 seeds: tests/learning_thresholds.md


def member_estimates(teacher: str, seed: int, augment: str, overlap: float) -> dict[str, dict]:
    """`seqrank simulate`'s crowd cell: 20 sequential sessions of 30 questions, each
    member estimated as training estimates them (`peer_reliability`, not this file's
    estimator, since simulate uses it)."""
    crowd = CrowdSource(parse_teacher(teacher).members, overlap)
    recheck = Recheck() if augment == "checked" else None
    rng = np.random.default_rng(seed)
    _, members = run_crowd_sessions("sequential", crowd, 30, 20, rng, recheck)
    return {str(row["name"]): row for row in members}


def test_reliability_from_overlaps_ranks_an_oracle_above_a_careless_member():
    """Three members, each answer asked again of another with probability 0.3, no model:
    the overlaps alone rank the oracle above the member who errs three times in ten."""
    teacher = "crowd:oracle+mistake,eps_mistake=0.3,name=mistake+noisy"
    gaps = []
    for seed in range(3):
        rows = member_estimates(teacher, seed, "full", 0.3)
        oracle, careless = rows["oracle"], rows["mistake"]
        assert oracle["true_error_rate"] == 0.0
        assert 0.2 < careless["true_error_rate"] < 0.4  # (it does err clearly)
        assert oracle["estimate"] > careless["estimate"]
        # the estimate is the careless member's share of right answers, give or take
        assert abs(careless["estimate"] - (1 - careless["true_error_rate"])) < 0.15
        gaps.append(oracle["estimate"] - careless["estimate"])
    assert np.mean(gaps) > 0.1


def test_reliability_from_contradictions_ranks_an_oracle_above_a_careless_member():
    """Two members only, whose overlaps cannot tell them apart: `augment checked` asks big
    answers again of the same person, and the careless member's contradictions do."""
    teacher = "crowd:oracle+mistake,eps_mistake=0.3,name=mistake"
    gaps = []
    for seed in range(3):
        rows = member_estimates(teacher, seed, "checked", 0.1)
        oracle, careless = rows["oracle"], rows["mistake"]
        assert oracle["estimate"] > careless["estimate"]
        gaps.append(oracle["estimate"] - careless["estimate"])
    assert np.mean(gaps) > 0.15
    full = member_estimates(teacher, 0, "full", 0.1)
    assert math.isclose(full["oracle"]["estimate"], full["mistake"]["estimate"], rel_tol=1e-9)
