"""Crowd weighting `reask` (issue 49, item 3): each question of a member flagged before a
session asked again of someone who is not, whose answer trains in place of theirs; the
flagged member's labels left out as under `drop`; nobody flagged, exactly `drop`."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from seqrank.config import resolve_config
from seqrank.episodes import Segments
from seqrank.feedback.crowd import CrowdSource
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.reliability import Reliability
from seqrank.feedback.schemes import SessionRecord, segments_needed, uniform_choice
from seqrank.feedback.session import SessionPlan, SessionRequest, store_session
from seqrank.feedback.teachers import parse_teacher
from seqrank.simulate import synthetic_segments
from seqrank.training import sessions as sessions_module
from seqrank.training.sessions import FeedbackSessions, Schedule
from seqrank.training.state import Counters
from seqrank.types import Answer

# two oracles and a member who is always wrong, each at their own pace
WRONG = "crowd:oracle,time=2+oracle,time=3+mistake,eps_mistake=1.0,name=bad,time=5"
QUESTIONS = 24
Session = tuple[SessionRequest, SessionRecord]


def make_request(
    session: int, rng: np.random.Generator, distrusted: frozenset[str] = frozenset()
) -> SessionRequest:
    """A sequential session of `QUESTIONS` for three chains, on a fresh synthetic pool."""
    rewards = synthetic_segments(segments_needed("sequential", QUESTIONS, 3), 20, rng)
    pool = Segments(rewards[:, :, None], rewards, [None] * len(rewards), [None] * len(rewards))
    return SessionRequest(
        "sequential", QUESTIONS, session, pool, uniform_choice, rng,
        float(rewards.sum(axis=1).mean()), chains=3, distrusted=distrusted,
    )  # fmt: skip


def run_sessions(
    value: str, weighting: str, sessions: int, until: int = 20
) -> tuple[LabelStore, list[Session]]:
    """A crowd's sessions into a store, each request told who is distrusted as a run
    tells it (`LabelStore.distrusted`)."""
    source = CrowdSource(parse_teacher(value).members, overlap=0.1, overlap_until=until)
    labels, rng, asked = LabelStore(weighting), np.random.default_rng(3), []
    for session in range(sessions):
        request = make_request(session, rng, labels.distrusted())
        _, record = source.ask_session(request)
        store_session(request.segments, record, labels, request)
        asked.append((request, record))
    return labels, asked


def right_labels(asked: list[Session], owner: str) -> dict[tuple[int, int], float]:
    """Store ids of each question `owner` was asked in a session that distrusted them,
    with its true label."""
    right, used = {}, 0
    for request, record in asked:
        assert record.crowd is not None
        returns = request.segments.rewards.sum(axis=1)
        offset = {pool_id: used + k for k, pool_id in enumerate(record.segments)}
        used += len(record.segments)
        for answer, name in zip(record.answers, record.crowd.answered_by, strict=True):
            if name == owner and owner in request.distrusted:
                better = returns[answer.first] > returns[answer.second]
                right[(offset[answer.first], offset[answer.second])] = float(better)
    return right


def test_a_flagged_members_questions_train_on_the_others_right_answers():
    labels, asked = run_sessions(WRONG, "reask", sessions=3)
    # flagged after the first session (every answer checked twice while evidence is short)
    assert [sorted(request.distrusted) for request, _ in asked] == [[], ["bad"], ["bad"]]
    assert labels.reliability()["bad"].flagged
    right = right_labels(asked, "bad")
    assert len(right) == 2 * QUESTIONS // 3
    trained: dict[tuple[int, int], set[float]] = {}
    rows = zip(labels.first, labels.second, labels.training_labels(), labels.kept(), strict=True)
    for first, second, label, kept in rows:
        if kept:
            trained.setdefault((first, second), set()).add(label)
    for pair, label in right.items():
        assert trained.get(pair) == {label}, pair  # asked of others, and answered right
    kept_bad = [k for k, name in zip(labels.kept(), labels.annotator, strict=True) if name == "bad"]
    assert kept_bad and not any(kept_bad)  # none of bad's answers or closure pairs train
    assert len(labels.tensors(torch.device("cpu"))[1]) == sum(labels.kept())
    for _, record in asked[1:]:
        assert record.crowd is not None and record.asked == QUESTIONS  # no question spent
        reasked = [o for o in record.crowd.second_opinions if o.reask]
        assert reasked and {o.annotator for o in reasked} <= {"oracle", "oracle-2"}
        owners = {record.crowd.answered_by[o.answered.question.index] for o in reasked}
        assert owners == {"bad"}  # only the distrusted member's questions are asked again


def test_a_reask_costs_person_time_and_is_evidence_never_a_question():
    pace = {m.name: m.seconds for m in parse_teacher(WRONG).members}
    labels, asked = run_sessions(WRONG, "reask", sessions=2)
    request, record = asked[1]
    assert request.distrusted == {"bad"} and record.crowd is not None
    opinions = record.crowd.second_opinions
    reasks = sum(o.reask for o in opinions)
    assert reasks > 0 and len(record.answers) == QUESTIONS
    everyone = [*record.crowd.answered_by, *(o.annotator for o in opinions)]
    assert record.crowd.person_seconds == pytest.approx(sum(pace[name] for name in everyone))
    # every opinion is evidence beside the session's answers, none a question of the budget
    stored = len(labels.crowd_answers)
    assert stored == sum(len(r.answers) + len(r.crowd.second_opinions) for _, r in asked if r.crowd)


def test_a_flagged_members_answer_is_reasked_in_place_of_the_overlap():
    """One rule with the page (`overlap.reasked`, `reasks_wanted`): while evidence is short
    every answer has two other opinions; a flagged member's has two too, both re-asks of
    trusted members (once evidence suffices, one where the overlap asks none:
    `test_overlap`, and the page's `test_crowd_reask`)."""
    until, wanted = 1000, 2
    _, asked = run_sessions(WRONG, "reask", sessions=2, until=until)
    request, record = asked[1]
    assert request.distrusted == {"bad"} and record.crowd is not None
    opinions: dict[int, list] = {}
    for opinion in record.crowd.second_opinions:
        opinions.setdefault(opinion.answered.question.index, []).append(opinion)
    owners = record.crowd.answered_by
    for k, (answer, owner) in enumerate(zip(record.answers, owners, strict=True)):
        if owner == "bad":
            assert len(opinions[k]) == wanted and all(o.reask for o in opinions[k])
            assert {o.annotator for o in opinions[k]} <= {"oracle", "oracle-2"}
            assert len({o.annotator for o in opinions[k]}) == wanted
            pair = (answer.first, answer.second)
            assert all((o.answered.first, o.answered.second) == pair for o in opinions[k])
        elif answer.answer is not Answer.SKIP and until:
            assert len(opinions[k]) == 2 and not any(o.reask for o in opinions[k])
            assert owner not in {o.annotator for o in opinions[k]}


def test_nobody_flagged_reask_is_exactly_drop():
    good = "crowd:oracle+oracle+mistake,eps_mistake=0.05"
    reask, reask_sessions = run_sessions(good, "reask", sessions=3)
    drop, drop_sessions = run_sessions(good, "drop", sessions=3)
    assert not any(r.flagged for r in reask.reliability().values())
    assert [r for _, r in reask_sessions] == [r for _, r in drop_sessions]
    stored = ("first", "second", "labels", "inferred", "annotator", "crowd_answers", "asked")
    assert [getattr(reask, name) for name in stored] == [getattr(drop, name) for name in stored]
    assert reask.kept() == drop.kept() == [True] * len(reask.labels)
    cpu = torch.device("cpu")
    for ours, theirs in zip(reask.tensors(cpu), drop.tensors(cpu), strict=True):
        assert torch.equal(ours, theirs)


def flags(*names: str):
    """A `LabelStore.reliability` that flags `names` of a, b and c."""

    def reliability(_self: LabelStore) -> dict[str, Reliability]:
        return {
            name: Reliability(name, 0.1 if name in names else 0.99, 0.0, 1.0, 50, 0, None)
            for name in "abc"
        }

    return reliability


def test_only_reask_distrusts_and_nobody_when_everybody_is_flagged(monkeypatch):
    labels = LabelStore("reask")
    labels.crowd_answers = [(0, 1, "first", "a", None)]
    monkeypatch.setattr(LabelStore, "reliability", flags("a"))
    assert labels.distrusted() == {"a"}
    monkeypatch.setattr(LabelStore, "reliability", flags("a", "b", "c"))
    assert labels.distrusted() == frozenset()
    monkeypatch.setattr(LabelStore, "reliability", flags("a"))
    for other in ("drop", "none", "reliability"):
        labels.weighting = other
        assert labels.distrusted() == frozenset()


def test_a_crowd_that_trusts_nobody_asks_nobody_again():
    members = parse_teacher("crowd:oracle,name=a+oracle,name=b+oracle,name=c").members
    records = []
    for distrusted in (frozenset(), frozenset("abc")):
        request = make_request(0, np.random.default_rng(4), distrusted)
        records.append(CrowdSource(members, 0.1, 20).ask_session(request)[1])
    assert records[0] == records[1]


def test_a_run_tells_each_session_who_is_distrusted(monkeypatch):
    config = resolve_config("walker_walk", "small", {"teacher": WRONG, "crowd_weighting": "reask"})
    labels = LabelStore(config.crowd_weighting.value)
    labels.crowd_answers = [(0, 1, "first", "a", None)]
    monkeypatch.setattr(LabelStore, "reliability", flags("a"))
    plain = make_request(1, np.random.default_rng(0))
    monkeypatch.setattr(sessions_module, "prepare_session", lambda *args, **kwargs: plain)
    episodes = type("Episodes", (), {"recent_returns": lambda _self, n: np.zeros(1)})()
    plan = SessionPlan("sequential", "uniform", 1, 20, crowd=3)
    run = FeedbackSessions(
        Schedule(48, 24, 500, 100), plan, None, episodes, None, None, True, labels
    )  # type: ignore[arg-type]
    assert run._request(Counters(sessions=1), first=False).distrusted == {"a"}
    labels.weighting = "drop"
    assert run._request(Counters(sessions=1), first=False) == plain


def test_a_runs_feedback_row_counts_its_reasks():
    """`metrics.jsonl`'s feedback row of a crowd session says how many of its second
    opinions asked a flagged member's question again, as the benchmark's rows do."""
    from seqrank.training.metrics import crowd_fields

    _, asked = run_sessions(WRONG, "reask", sessions=2)
    first, second = (record.crowd for _, record in asked)
    assert first is not None and second is not None
    assert crowd_fields(first, {})["reasks"] == 0  # nobody flagged yet
    row = crowd_fields(second, {})
    assert row["reasks"] == sum(o.reask for o in second.second_opinions) > 0
    assert row["second_opinions"] == len(second.second_opinions) >= row["reasks"]
