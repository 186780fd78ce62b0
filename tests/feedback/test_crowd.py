"""A simulated crowd (`seqrank.feedback.crowd`): each session shared out as chains, one a
person, second opinions asked of someone else and kept out of the closure, and the crowd's
settings (`--teacher crowd:...`, `overlap`, `crowd_weighting`)."""

from __future__ import annotations

import math
from collections import Counter, defaultdict

import numpy as np
import pytest

from seqrank.config import resolve_config
from seqrank.episodes import Segments
from seqrank.errors import SettingError
from seqrank.feedback import session as session_module
from seqrank.feedback.checking import Recheck
from seqrank.feedback.crowd import CrowdSource, share_session
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.schemes import SCHEMES, handover_reserve, segments_needed, uniform_choice
from seqrank.feedback.session import ScriptedSource, SessionRequest, store_session
from seqrank.feedback.teachers import (
    ScriptedTeacher,
    TeacherConfig,
    parse_teacher,
    teacher_preset,
)
from seqrank.simulate import synthetic_segments
from seqrank.types import Answer

CROWD = "crowd:oracle+mistake+noisy"


def make_pool(count: int, seed: int, horizon: int = 20) -> Segments:
    """`count` synthetic segments (the simulator's), features = the per-step rewards."""
    rewards = synthetic_segments(count, horizon, np.random.default_rng(1000 + seed))
    return Segments(rewards[:, :, None], rewards, [None] * count, [None] * count)


def make_request(
    scheme: str,
    questions: int,
    pool: Segments,
    seed: int,
    chains: int = 1,
    recheck: Recheck | None = None,
    model_returns: tuple[float, ...] | None = None,
    chooser=uniform_choice,
) -> SessionRequest:
    margin = float(pool.rewards.sum(axis=1).mean())
    return SessionRequest(
        scheme, questions, 0, pool, chooser, np.random.default_rng(seed), margin,
        recheck=recheck, model_returns=model_returns, chains=chains,
    )  # fmt: skip


def crowd(value: str = CROWD, overlap: float = 0.3) -> CrowdSource:
    return CrowdSource(parse_teacher(value).members, overlap)


def within_binomial(observed: float, p: float, n: int, z: float = 4.0) -> bool:
    return abs(observed - p) <= z * math.sqrt(p * (1 - p) / n)


# --- a crowd of one ---------------------------------------------------------------------


@pytest.mark.parametrize("scheme", list(SCHEMES))
@pytest.mark.parametrize("preset", ["oracle", "mistake", "noisy"])
@pytest.mark.parametrize("checking", ["none", "recheck", "recheck with a model"])
def test_a_crowd_of_one_asks_exactly_what_one_scripted_teacher_asks(scheme, preset, checking):
    questions = 12
    pool = make_pool(2 * questions, seed=3)
    returns = pool.rewards.sum(axis=1)
    recheck = {
        "none": None,
        "recheck": Recheck(),
        # a fitted model's opinion of each segment: mostly right, so some answers are vouched
        "recheck with a model": Recheck(model_returns=tuple(returns + 3 * np.sin(returns))),
    }[checking]
    for seed in range(3):
        alone = make_request(scheme, questions, pool, seed, recheck=recheck)
        shared = make_request(scheme, questions, pool, seed, recheck=recheck)
        teacher = ScriptedSource(ScriptedTeacher(teacher_preset(preset)))
        _, expected = teacher.ask_session(alone)
        _, got = crowd(f"crowd:{preset}", overlap=0.5).ask_session(shared)
        assert got.answers == expected.answers
        assert got.segments == expected.segments
        assert got.vouched == expected.vouched
        assert got.crowd is not None
        assert got.crowd.answered_by == (preset,) * len(expected.answers)
        assert got.crowd.second_opinions == ()  # nobody else to ask
        # and the session's generator is left where the teacher's is: the run draws on alike
        assert shared.rng.random() == alone.rng.random()


# --- three members: one chain a person ----------------------------------------------------


@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_three_members_answer_their_own_chains_and_the_closure_never_mixes_them(
    scheme, monkeypatch
):
    source = crowd(CROWD, overlap=0.4)
    names = [m.name for m in source.members]
    closure_inputs: list[list] = []
    real_augment = session_module.augment

    def spy(answers, *args, **kwargs):
        answers = list(answers)
        closure_inputs.append(answers)
        return real_augment(answers, *args, **kwargs)

    monkeypatch.setattr(session_module, "augment", spy)
    inferred_seen = 0
    for seed in range(5):
        questions = 10 + seed  # uneven splits too
        pool = make_pool(segments_needed(scheme, questions, 3) + seed, seed)
        request = make_request(scheme, questions, pool, seed, chains=3)
        returned, record = source.ask_session(request)
        assert returned is pool
        people = record.crowd
        assert people is not None
        # the owners' answers are the session's questions, numbered in order
        assert len(record.answers) == len(people.answered_by) == questions
        assert [a.question.index for a in record.answers] == list(range(questions))
        chains, _ = share_session(scheme, questions, len(pool.rewards), 3)
        assert Counter(people.answered_by) == {names[k]: c.budget for k, c in enumerate(chains)}
        # each answer lies inside its owner's slice, so no segment is seen by two owners
        slice_owner = {i: names[k] for k, c in enumerate(chains) for i in c.pool_ids}
        seen_by = defaultdict(set)
        for asked, owner in zip(record.answers, people.answered_by, strict=True):
            assert slice_owner[asked.first] == slice_owner[asked.second] == owner
            seen_by[asked.first].add(owner)
            seen_by[asked.second].add(owner)
        assert all(len(owners) == 1 for owners in seen_by.values())
        assert {slice_owner[s] for s in record.segments} <= set(names)
        # second opinions: an owner's question asked again of somebody else, once at most
        for opinion in people.second_opinions:
            k = opinion.answered.question.index
            again, first_time = opinion.answered, record.answers[k]
            assert (again.first, again.second) == (first_time.first, first_time.second)
            assert opinion.annotator in names and opinion.annotator != people.answered_by[k]
            assert first_time.answer is not Answer.SKIP
        indices = [o.answered.question.index for o in people.second_opinions]
        assert len(indices) == len(set(indices))

        labels = LabelStore()
        closure_inputs.clear()
        store_session(pool, record, labels, request)
        # the closure is given the owners' answers only, never a second opinion
        assert closure_inputs == [list(record.answers)]
        # no inferred pair joins two people's segments; each pair is its owner's
        owner_of_stored = [slice_owner[pool_id] for pool_id in record.segments]
        for first, second, inferred, annotator in zip(
            labels.first, labels.second, labels.inferred, labels.annotator, strict=True
        ):
            if inferred:
                inferred_seen += 1
                assert owner_of_stored[first] == owner_of_stored[second] == annotator
        # second opinions are stored as asked pairs of their own, by whoever gave them
        strict_seconds = [o for o in people.second_opinions if o.answered.answer.label is not None]
        answered = sum(a.answer.label is not None for a in record.answers)
        assert labels.inferred.count(False) == answered + len(strict_seconds)
        stored_opinions = labels.annotator[len(labels) - len(strict_seconds) :]
        assert stored_opinions == [o.annotator for o in strict_seconds]
        # and every answer, second opinions too, is reliability evidence under its person
        assert [row[3] for row in labels.crowd_answers] == [
            *people.answered_by,
            *(o.annotator for o in people.second_opinions),
        ]
    if scheme != "pairwise":  # (pairwise infers nothing: the check above must not be idle)
        assert inferred_seen > 0


@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_second_opinions_are_asked_of_about_overlap_of_the_answers(scheme):
    overlap, questions = 0.3, 12
    # a skipping member, so that skipped answers (never asked again) are in the mix
    source = crowd("crowd:oracle+skip,eps_skip=0.5+noisy", overlap)
    answered = asked_again = skipped = 0
    for seed in range(80):
        pool = make_pool(segments_needed(scheme, questions, 3), seed)
        _, record = source.ask_session(make_request(scheme, questions, pool, seed, chains=3))
        assert record.crowd is not None
        answered += sum(a.answer is not Answer.SKIP for a in record.answers)
        skipped += sum(a.answer is Answer.SKIP for a in record.answers)
        asked_again += len(record.crowd.second_opinions)
        for opinion in record.crowd.second_opinions:  # a skipped question is not asked again
            assert record.answers[opinion.answered.question.index].answer is not Answer.SKIP
    assert skipped > 0
    assert within_binomial(asked_again / answered, overlap, answered)


@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_overlap_zero_asks_nobody_again_and_one_asks_every_answer_again(scheme):
    questions, skipping = 9, "crowd:oracle+skip,eps_skip=0.5+noisy"
    pool = make_pool(segments_needed(scheme, questions, 3), seed=5)
    _, none = crowd(CROWD, 0.0).ask_session(make_request(scheme, questions, pool, 1, chains=3))
    _, every = crowd(CROWD, 1.0).ask_session(make_request(scheme, questions, pool, 1, chains=3))
    assert none.crowd is not None and every.crowd is not None
    assert none.crowd.second_opinions == ()
    indices = [o.answered.question.index for o in every.crowd.second_opinions]
    assert indices == list(range(questions))  # (nobody in this crowd skips)
    # every answer but the skipped ones
    skipped_seen = 0
    for seed in range(10):
        pool = make_pool(segments_needed(scheme, questions, 3), seed)
        request = make_request(scheme, questions, pool, seed, chains=3)
        _, record = crowd(skipping, 1.0).ask_session(request)
        assert record.crowd is not None
        indices = [o.answered.question.index for o in record.crowd.second_opinions]
        assert indices == [k for k, a in enumerate(record.answers) if a.answer is not Answer.SKIP]
        skipped_seen += len(record.answers) - len(indices)
    assert skipped_seen > 0


def test_the_session_lasts_as_long_as_its_slowest_person():
    """Members answer side by side: the session's length is the longest of their
    answering times (answers x seconds each), `person_seconds` their sum."""
    source = crowd("crowd:oracle,time=2+oracle,time=5", overlap=0.0)
    pool = make_pool(20, seed=0)
    _, record = source.ask_session(make_request("pairwise", 10, pool, 0, chains=2))
    assert record.crowd is not None
    assert Counter(record.crowd.answered_by) == {"oracle": 5, "oracle-2": 5}
    assert record.crowd.seconds == pytest.approx(5 * 5.0)
    assert record.crowd.person_seconds == pytest.approx(5 * 2.0 + 5 * 5.0)


def test_the_model_opinion_of_each_asked_pair_is_the_logistic_of_its_return_difference():
    pool = make_pool(24, seed=2)
    model = tuple(float(r) for r in 0.1 * pool.rewards.sum(axis=1))
    request = make_request("sequential", 12, pool, 0, chains=3, model_returns=model)
    _, record = crowd(CROWD, overlap=0.5).ask_session(request)
    assert record.crowd is not None
    asked = [*record.answers, *(o.answered for o in record.crowd.second_opinions)]
    assert len(record.crowd.model_first) == len(asked)
    for a, p in zip(asked, record.crowd.model_first, strict=True):
        assert p == pytest.approx(1 / (1 + math.exp(model[a.second] - model[a.first])))
    _, unfit = crowd(CROWD, overlap=0.5).ask_session(make_request("sequential", 12, pool, 0, 3))
    assert unfit.crowd is not None and set(unfit.crowd.model_first) == {None}


@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_each_chain_chooses_and_rechecks_within_its_own_slice(scheme):
    """The chooser is shown pool ids of one chain's slice only, and the re-check's model
    opinions (given for the whole pool) follow the chain's segments."""
    questions = 12
    pool = make_pool(segments_needed(scheme, questions, 3), seed=4)
    chains, _ = share_session(scheme, questions, len(pool.rewards), 3)
    slice_of = {i: k for k, c in enumerate(chains) for i in c.pool_ids}
    calls = []

    def chooser(defender, available, rng):
        calls.append((defender, list(available)))
        return int(np.argmax(available))  # the largest id: a choice that depends on the ids

    returns = pool.rewards.sum(axis=1)
    recheck = Recheck(model_returns=tuple(returns.tolist()))  # a perfect model vouches
    request = make_request(scheme, questions, pool, 0, 3, recheck, chooser=chooser)
    _, record = crowd(CROWD, overlap=0.0).ask_session(request)
    assert calls
    for defender, available in calls:
        chain = {slice_of[i] for i in available}
        assert len(chain) == 1
        assert defender is None or {slice_of[defender]} == chain
    # every chain's first choice is among its whole slice
    whole = [
        available for _, available in calls if len(available) in {len(c.pool_ids) for c in chains}
    ]
    assert sorted(map(tuple, whole)) == sorted(c.pool_ids for c in chains)
    # each chain took the largest ids of its slice first
    firsts = {}
    for pool_id in record.segments:
        firsts.setdefault(slice_of[pool_id], pool_id)
    assert firsts == {k: max(c.pool_ids) for k, c in enumerate(chains)}
    for winner, loser in record.vouched:
        assert slice_of[winner] == slice_of[loser]
        assert returns[winner] > returns[loser]


# --- sharing a session ---------------------------------------------------------------------


def test_share_session_splits_the_questions_evenly_the_first_chains_taking_the_rest():
    chains, reserve = share_session("sequential", 10, 16, 3)
    assert [c.budget for c in chains] == [4, 3, 3]
    assert [c.pool_ids for c in chains] == [
        tuple(range(0, 5)),
        tuple(range(5, 9)),
        tuple(range(9, 13)),
    ]
    assert reserve == (13, 14, 15)  # one segment a chain, for a chain handed over
    # pairwise: 8, 6 and 6 segments needed, a pool of 45 holds twice that and 5 over; a
    # pair handed over needs no new first segment, so pairwise keeps no reserve
    chains, reserve = share_session("pairwise", 10, 45, 3)
    assert [c.budget for c in chains] == [4, 3, 3]
    assert [len(c.pool_ids) for c in chains] == [16, 12, 17] and reserve == ()


def test_share_session_makes_no_chain_beyond_the_questions():
    chains, _ = share_session("root", 2, 10, 5)
    assert [c.budget for c in chains] == [1, 1]
    assert share_session("ranked", 1, 4, 3)[0][0].budget == 1
    assert len(share_session("ranked", 1, 4, 3)[0]) == 1


@pytest.mark.parametrize("scheme", list(SCHEMES))
@pytest.mark.parametrize("questions", [1, 2, 3, 7, 10, 31])
@pytest.mark.parametrize("people", [1, 2, 3, 5])
@pytest.mark.parametrize("extra", [0, 1, 7, 40])
def test_share_session_cuts_the_pool_into_disjoint_contiguous_slices_that_suffice(
    scheme, questions, people, extra
):
    pool = segments_needed(scheme, questions, people) + extra
    chains, reserve = share_session(scheme, questions, pool, people)
    budgets = [c.budget for c in chains]
    assert sum(budgets) == questions
    assert len(chains) == min(people, questions)
    assert max(budgets) - min(budgets) <= 1 and budgets == sorted(budgets, reverse=True)
    # slices in order, each contiguous, then the reserve: together the whole pool
    assert [i for c in chains for i in c.pool_ids] + list(reserve) == list(range(pool))
    assert len(reserve) == handover_reserve(scheme, questions, people)
    for c in chains:
        assert list(c.pool_ids) == list(range(c.pool_ids[0], c.pool_ids[-1] + 1))
        assert len(c.pool_ids) >= segments_needed(scheme, c.budget)


@pytest.mark.parametrize(
    ("scheme", "pool", "needed"), [("sequential", 15, 16), ("pairwise", 19, 20)]
)
def test_share_session_names_the_sizes_when_the_pool_is_too_small(scheme, pool, needed):
    with pytest.raises(ValueError, match=rf"\[4, 3, 3\].*need {needed} segments.*has {pool}"):
        share_session(scheme, 10, pool, 3)
    with pytest.raises(ValueError, match="at least one person"):
        share_session(scheme, 10, 100, 0)


def test_segments_needed_counts_one_first_segment_and_one_spare_per_chain():
    assert segments_needed("sequential", 10) == 11
    assert segments_needed("sequential", 10, 3) == 16  # 4 + 1, 3 + 1, 3 + 1, and 3 spare
    assert segments_needed("root", 10, 3) == 16
    assert segments_needed("ranked", 10, 3) == 16
    assert segments_needed("root", 2, 5) == 6  # two chains only: one question each
    assert segments_needed("root", 5, 1) == 6  # one chain: no spare
    assert segments_needed("pairwise", 10, 3) == 20  # disjoint pairs, however shared


# --- the crowd's teacher spec -----------------------------------------------------------


def test_crowd_members_are_named_by_their_preset_and_numbered_when_repeated():
    spec = parse_teacher("crowd:oracle+mistake+oracle+noisy+oracle")
    assert spec.kind == "crowd"
    names = [m.name for m in spec.members]
    assert names == ["oracle", "mistake", "oracle-2", "noisy", "oracle-3"]
    assert spec.short_name == "crowd-" + "+".join(names)
    assert [m.teacher for m in spec.members] == [
        teacher_preset(p) for p in ("oracle", "mistake", "oracle", "noisy", "oracle")
    ]
    assert all(m.seconds == 3.0 for m in spec.members)


def test_crowd_members_take_knobs_time_and_name():
    spec = parse_teacher("crowd:mistake,eps_mistake=0.3,time=1.5,name=sloppy+noisy,beta=2")
    sloppy, noisy = spec.members
    assert (sloppy.name, sloppy.seconds) == ("sloppy", 1.5)
    assert sloppy.teacher == TeacherConfig(eps_mistake=0.3)
    assert noisy.teacher.beta == 2.0 and noisy.seconds == 3.0
    assert parse_teacher("crowd:name=alice").members[0].teacher == teacher_preset("oracle")
    assert parse_teacher("crowd:oracle,name=bob-2").members[0].name == "bob-2"


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("crowd:oracle++noisy", "an empty crowd member"),
        ("crowd:", "an empty crowd member"),
        ("crowd:oracle+ ", "an empty crowd member"),
        ("crowd:oracle+perfect", "unknown teacher 'perfect'; accepted: oracle, mistake"),
        ("crowd:oracle+perfect", "a crowd member also takes time= and name="),
        ("crowd:oracle,time=0", "time must be a number of seconds > 0, got '0'"),
        ("crowd:oracle,time=-1", "time must be a number of seconds > 0, got '-1'"),
        ("crowd:oracle,time=soon", "time must be a number of seconds > 0, got 'soon'"),
        ("crowd:oracle,time=inf", "time must be a number of seconds > 0, got 'inf'"),
        ("crowd:oracle,time=nan", "time must be a number of seconds > 0, got 'nan'"),
        ("crowd:oracle,name=a+noisy,name=a", "member name 'a' must be letters, digits and '-'"),
        ("crowd:oracle,name=a+noisy,name=a", "taken: a"),
        ("crowd:oracle+noisy,name=oracle", "member name 'oracle'"),
        ("crowd:oracle,name=(model)", "member name '(model)'"),
        ("crowd:oracle,name=a b", "member name 'a b'"),
        ("crowd:oracle,name=", "member name ''"),
        ("crowd:oracle,eps_mistake=2", "eps_mistake must be in [0, 1], got 2.0"),
    ],
)
def test_a_bad_crowd_spec_names_what_is_wrong(value, message):
    with pytest.raises(SettingError) as raised:
        parse_teacher(value)
    assert message in str(raised.value)


# --- settings -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "setting",
    [
        {"overlap": 0.5},
        {"crowd_weighting": "reliability"},
        {"crowd_weighting": "none"},
        {"overlap_until": 40},
        {"closure_checks": 1},
    ],
)
def test_the_crowd_settings_are_refused_without_a_crowd(setting):
    (name,) = setting
    with pytest.raises(SettingError, match=rf"{name} act.* on a crowd's answers") as raised:
        resolve_config("walker_walk", "small", setting)
    assert "teacher 'oracle' is one teacher" in str(raised.value)
    config = resolve_config("walker_walk", "small", {**setting, "teacher": "crowd:oracle+noisy"})
    assert str(getattr(config, name)) == str(setting[name])
    assert [m.name for m in config.teacher_spec.members] == ["oracle", "noisy"]


@pytest.mark.parametrize("overlap", [1.5, -0.1, float("nan")])
def test_overlap_outside_zero_to_one_is_refused_naming_the_range(overlap):
    teacher = "crowd:oracle+noisy"
    with pytest.raises(SettingError, match=r"overlap must be a number in \[0, 1\], got"):
        resolve_config("walker_walk", "small", {"overlap": overlap, "teacher": teacher})
    for edge in (0.0, 1.0):
        config = resolve_config("walker_walk", "small", {"overlap": edge, "teacher": teacher})
        assert config.overlap == edge
