"""The adaptive overlap (`seqrank.feedback.overlap`): every answer asked again until each
member's answers shared with others reach `until`, a share `overlap` after; and a crowd
weighting `drop` that leaves a flagged member's labels out of reward training."""

from __future__ import annotations

from collections import Counter

import numpy as np
import torch

from seqrank.episodes import Segments
from seqrank.feedback.closure_checks import chain_inferences
from seqrank.feedback.crowd import CrowdSource
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.overlap import CHECKERS, checkers, opinions_wanted, reasks_wanted
from seqrank.feedback.reliability import Reliability
from seqrank.feedback.schemes import segments_needed, uniform_choice
from seqrank.feedback.session import SessionRequest, store_session
from seqrank.feedback.teachers import parse_teacher
from seqrank.simulate import synthetic_segments
from seqrank.types import Answer

CROWD = "crowd:oracle+mistake+mistake,eps_mistake=0.5,name=bad"


def crowd_sessions(
    source: CrowdSource, sessions: int, questions: int = 24, weighting: str = "none"
) -> tuple[LabelStore, list[int]]:
    """A three-person crowd's sequential sessions into a store; the second opinions asked
    in each session."""
    labels, rng, seconds = LabelStore(weighting), np.random.default_rng(3), []
    for session in range(sessions):
        rewards = synthetic_segments(segments_needed("sequential", questions, 3), 20, rng)
        pool = Segments(rewards[:, :, None], rewards, [None] * len(rewards), [None] * len(rewards))
        request = SessionRequest(
            "sequential", questions, session, pool, uniform_choice, rng,
            float(rewards.sum(axis=1).mean()), chains=3,
        )  # fmt: skip
        _, record = source.ask_session(request)
        assert record.crowd is not None
        seconds.append(len(record.crowd.second_opinions))
        store_session(pool, record, labels, request)
    return labels, seconds


def test_every_answer_is_asked_again_until_each_member_has_enough_shared_then_the_overlap():
    source = CrowdSource(parse_teacher(CROWD).members, overlap=0.0, overlap_until=20)
    labels, asked_again = crowd_sessions(source, sessions=5)
    assert asked_again[0] == 2 * 20  # every answer, by both others, until each has 20
    assert all(count >= 20 for count in source.shared.values())
    assert asked_again[-1] == 0  # enough evidence, and an overlap of 0 after it
    # three opinions on each pair checked: the owner's and two others', counted once each
    assert sum(source.shared.values()) == 3 * sum(asked_again) // 2
    pairs = Counter((f, s) for f, s, _, _, _ in labels.crowd_answers)
    assert set(pairs.values()) == {1, 3}


def test_after_the_evidence_one_other_person_is_asked_a_share_overlap_of_the_answers():
    source = CrowdSource(parse_teacher(CROWD).members, overlap=0.5, overlap_until=10)
    labels, asked_again = crowd_sessions(source, sessions=6)
    assert 0.3 * 24 < np.mean(asked_again[2:]) < 0.7 * 24
    pairs = Counter((f, s) for f, s, _, _, _ in labels.crowd_answers[-24 * 2 :])
    assert set(pairs.values()) <= {1, 2}


def test_overlap_until_zero_asks_as_a_fixed_overlap_did():
    members = parse_teacher(CROWD).members
    fixed, _ = crowd_sessions(CrowdSource(members, 0.3), sessions=2)
    zero, _ = crowd_sessions(CrowdSource(members, 0.3, overlap_until=0), sessions=2)
    assert fixed.crowd_answers == zero.crowd_answers


def test_others_are_asked_while_the_owner_lacks_evidence_or_by_the_draw():
    assert opinions_wanted(3, until=4, overlap=0.0, draw=0.99) == CHECKERS
    assert opinions_wanted(4, until=4, overlap=0.1, draw=0.5) == 0
    assert opinions_wanted(4, until=4, overlap=0.1, draw=0.05) == 1
    assert opinions_wanted(0, until=1, overlap=0.0, draw=0.5) == CHECKERS


def test_a_flagged_members_answer_is_reasked_as_often_as_the_overlap_asks_at_least_once():
    assert reasks_wanted(3, until=4, overlap=0.0, draw=0.99) == CHECKERS
    assert reasks_wanted(4, until=4, overlap=0.1, draw=0.05) == 1
    assert reasks_wanted(4, until=4, overlap=0.1, draw=0.5) == 1  # (the overlap asks none)


def test_the_checkers_are_the_other_people_with_the_fewest_shared_answers():
    rng = np.random.default_rng(0)
    people, shared = ["a", "b", "c", "d"], {"a": 0, "b": 9, "c": 2, "d": 5}
    assert {tuple(checkers(shared, "a", people, rng)) for _ in range(20)} == {("c",)}
    assert checkers(shared, "a", people, rng, count=2) == ["c", "d"]
    assert sorted(checkers(shared, "a", people, rng, count=5)) == ["b", "c", "d"]
    tied = {checkers({"b": 1, "c": 1}, "a", ["a", "b", "c"], rng)[0] for _ in range(40)}
    assert tied == {"b", "c"}


def test_drop_leaves_a_flagged_members_labels_out_and_keeps_the_rest():
    source = CrowdSource(parse_teacher(CROWD).members, overlap=0.1, overlap_until=40)
    labels, _ = crowd_sessions(source, sessions=6, weighting="drop")
    trust = labels.reliability()
    assert trust["bad"].flagged and not trust["oracle"].flagged
    kept = labels.kept()
    assert [k for k, name in zip(kept, labels.annotator, strict=True) if name == "bad"] == [
        False
    ] * labels.annotator.count("bad")
    assert all(k for k, name in zip(kept, labels.annotator, strict=True) if name != "bad")
    _, first, _, fitted = labels.tensors(torch.device("cpu"))
    assert len(first) == len(fitted) == sum(kept) == len(labels.asked_mask())
    asked = [not i for i, k in zip(labels.inferred, kept, strict=True) if k]
    assert labels.asked_mask().tolist() == asked
    # as answered: every label, the same store
    labels.weighting = "none"
    assert len(labels.tensors(torch.device("cpu"))[1]) == len(labels.labels)


def test_drop_keeps_everything_when_nobody_is_flagged():
    labels, _ = crowd_sessions(
        CrowdSource(parse_teacher("crowd:oracle+oracle+oracle").members, 0.1, 40),
        sessions=3,
        weighting="drop",
    )
    assert not any(r.flagged for r in labels.reliability().values())
    assert labels.kept() == [True] * len(labels.labels)


def test_drop_keeps_everything_when_everybody_is_flagged(monkeypatch):
    labels = LabelStore("drop")
    labels.labels, labels.annotator, labels.inferred = [1.0, 0.0], ["a", "b"], [False, True]

    def everyone(_self: LabelStore) -> dict[str, Reliability]:
        return {name: Reliability(name, 0.1, 0.0, 0.2, 50, 0, None) for name in "ab"}

    monkeypatch.setattr(LabelStore, "reliability", everyone)
    assert labels.kept() == [True, True]


# --- closure checks: a second opinion on a pair the owner's chain inferred ---------------


def test_closure_checks_ask_inferred_pairs_and_count_the_implied_order_as_the_owners():
    source = CrowdSource(parse_teacher(CROWD).members, 0.0, 20, closure_checks=True)
    labels, asked_again = crowd_sessions(source, sessions=2)
    # one more row of evidence for each check on an inferred pair: the owner's implied answer
    checks = len(labels.crowd_answers) - (2 * 24 + sum(asked_again))
    assert checks > 10
    plain, _ = crowd_sessions(CrowdSource(parse_teacher(CROWD).members, 0.0, 20), sessions=2)
    assert len(plain.crowd_answers) == 2 * 24 + sum(asked_again)


def test_an_oracles_chain_implies_the_true_order_and_a_check_is_never_an_asked_pair():
    source = CrowdSource(parse_teacher("crowd:oracle+oracle").members, 0.0, 100, True)
    rng = np.random.default_rng(5)
    rewards = synthetic_segments(segments_needed("sequential", 20, 2), 20, rng)
    returns = rewards.sum(axis=1)
    pool = Segments(rewards[:, :, None], rewards, [None] * len(rewards), [None] * len(rewards))
    request = SessionRequest(
        "sequential", 20, 0, pool, uniform_choice, rng, float(returns.mean()), chains=2
    )
    _, record = source.ask_session(request)
    assert record.crowd is not None
    asked = {(a.first, a.second) for a in record.answers}
    inferred = chain_inferences(record)
    checks = [o for o in record.crowd.second_opinions if o.implied is not None]
    assert len(checks) >= 10
    for opinion in checks:
        pair = (opinion.answered.first, opinion.answered.second)
        assert opinion.implied is not None
        owner, answer = opinion.implied
        assert pair not in asked
        assert any((p.first, p.second) == pair for p in inferred[owner])
        truth = Answer.FIRST if returns[pair[0]] > returns[pair[1]] else Answer.SECOND
        assert answer is truth and opinion.answered.answer is truth
