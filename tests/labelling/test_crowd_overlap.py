"""The labelling page's adaptive overlap (issue 49): while a member's answers shared with
somebody else are fewer than `overlap_until`, each of their answers is asked of two others
(never one person twice); after that, only the share `overlap`; a replay poses nothing new,
and an opinion nobody takes is withdrawn once the chains are done."""

from __future__ import annotations

import time
from collections import defaultdict
from threading import Event, Thread

import numpy as np

from seqrank.episodes import Segments
from seqrank.labelling.crowd_db import CrowdTables
from seqrank.labelling.crowd_keys import (
    OPINION_STRIDE,
    SECOND_OPINIONS,
    ChainStep,
    SecondOpinionOf,
    key_of,
)
from seqrank.labelling.db import LabelDB
from support.crowd import answering, bare_team, team_request

TEAM = ["alice", "bob", "carol"]


def _choice(question) -> str:
    return ("left", "right")[(question.left * 7 + question.right) % 2]


def _opinions(tables: CrowdTables, session: int = 0) -> dict[tuple[int, int], list[str]]:
    """Each answered chain question's (first, second): its author, then who else answered."""
    chain_answers, others = {}, defaultdict(list)
    for question, who, chain, _, _ in tables.answered_by():
        if question.session != session:
            continue
        pair = (question.first, question.second)
        if chain == SECOND_OPINIONS:
            others[pair].append(who)
        else:
            chain_answers[pair] = who
    return {pair: [author, *others[pair]] for pair, author in chain_answers.items()}


def _stop(done: Event, people: list) -> None:
    done.set()
    for person in people:
        person.join(10)


def _shared_before(db: LabelDB, pairs: int, people: tuple[str, ...]) -> None:
    """An earlier session (number 9) in which `people` answered the same `pairs` pairs."""
    tables = CrowdTables(db)
    n = 2 * pairs
    pool = Segments(np.zeros((n, 3, 4), np.float32), np.zeros((n, 3)), [None] * n, [None] * n)
    db.create_session("offline", 9, "pairwise", pairs, 0, "left", pool)
    ids = sorted(db.segment_ids("offline", 9).values())
    for k in range(pairs):
        a, b = ids[2 * k], ids[2 * k + 1]
        for j, name in enumerate(people):
            question = db.ensure_question("offline", 9, j * 1000 + k, a, b, None, a, b)
            tables.pose(question, 0, name, None)
            tables.record_answer(question, "left", 5.0, name)


def test_the_next_opinions_have_keys_of_their_own_and_the_first_keeps_its_old_one():
    assert SecondOpinionOf(ChainStep(2, 7)).index == -200_008  # as stored before
    later = SecondOpinionOf(ChainStep(2, 7), 1)
    assert later.index == -(OPINION_STRIDE + 200_008) and key_of(later.index) == later
    assert key_of(SecondOpinionOf(ChainStep(0, 0), 3).index) == SecondOpinionOf(ChainStep(0, 0), 3)


def test_each_answer_of_a_member_short_of_evidence_is_asked_of_both_others(tmp_path):
    hub = bare_team(tmp_path, TEAM, 60.0, overlap=0.0, overlap_until=1000)
    done = Event()
    people = [answering(hub, name, _choice, done) for name in TEAM]
    _, record = hub.source("offline", 3).ask_session(team_request("sequential", 12, 3, spare=2))
    _stop(done, people)
    opinions = _opinions(hub.crowd.tables)
    assert len(opinions) == 12
    for pair, (author, *others) in opinions.items():
        assert sorted(others) == sorted(set(TEAM) - {author}), pair  # both others, once each
    assert record.crowd is not None and len(record.crowd.second_opinions) == 24
    hub.db.close()


def test_once_a_member_has_enough_shared_answers_only_the_share_is_asked_again(tmp_path):
    """alice and bob shared 20 answers before; carol none: with `overlap_until` 20 and no
    share, only carol's answers are asked again, each of alice and bob."""
    hub = bare_team(tmp_path, TEAM, 60.0, overlap=0.0, overlap_until=20)
    _shared_before(hub.db, 20, ("alice", "bob"))
    tables = hub.crowd.tables
    assert [tables.shared_answers("offline", n) for n in TEAM] == [20, 20, 0]
    done = Event()
    people = [answering(hub, name, _choice, done) for name in TEAM]
    hub.source("offline", 3).ask_session(team_request("sequential", 9, 3, spare=2))
    _stop(done, people)
    opinions = _opinions(tables)
    carols = [others for author, *others in opinions.values() if author == "carol"]
    theirs = [others for author, *others in opinions.values() if author != "carol"]
    assert carols and all(sorted(o) == ["alice", "bob"] for o in carols)
    assert theirs and all(o == [] for o in theirs)
    hub.db.close()


def test_a_replayed_session_poses_no_opinion_it_did_not_pose_before(tmp_path):
    hub = bare_team(tmp_path, TEAM, 60.0, overlap=0.3, overlap_until=4)
    done = Event()
    people = [answering(hub, name, _choice, done) for name in TEAM]
    request = team_request("root", 12, 3, spare=2)
    _, first = hub.source("offline", 5).ask_session(request)
    _stop(done, people)
    posed = "SELECT question_id, chain, excluded FROM crowd_questions ORDER BY question_id"
    before = [tuple(row) for row in hub.db.rows(posed)]
    assert any(isinstance(key_of(q.index), ChainStep) is False for q, *_ in
               hub.crowd.tables.answered_by())  # fmt: skip
    _, again = hub.source("offline", 5).ask_session(team_request("root", 12, 3, spare=2))
    assert [tuple(row) for row in hub.db.rows(posed)] == before
    assert again.answers == first.answers
    assert again.crowd is not None and first.crowd is not None
    assert again.crowd.second_opinions == first.crowd.second_opinions
    hub.db.close()


def test_an_opinion_nobody_takes_is_withdrawn_once_the_chains_are_done(tmp_path):
    """bob never comes: alice's answers are asked of him, nobody takes them, and the
    session ends `reassign_after` after its chains, without them."""
    hub = bare_team(tmp_path, ["alice", "bob"], 0.5, overlap=0.0, overlap_until=1000)
    done = Event()
    people = [answering(hub, "alice", _choice, done)]
    started = time.monotonic()
    _, record = hub.source("offline", 3).ask_session(team_request("pairwise", 4, 2, spare=2))
    _stop(done, people)
    assert time.monotonic() - started < 30
    assert record.crowd is not None and record.crowd.second_opinions == ()
    rows = hub.db.rows(f"SELECT withdrawn_at FROM crowd_questions WHERE chain = {SECOND_OPINIONS}")
    assert len(rows) == 4 and all(row["withdrawn_at"] is not None for row in rows)
    hub.db.close()


def test_an_opinion_taken_before_the_chains_end_plus_the_wait_is_waited_for(tmp_path):
    """Two opinions are open when the chains end: xav takes the first 1 s later and answers
    it 4.5 s later, ann takes the second 2 s later and answers it 5.2 s later (each within
    the 4 s a taken question is given). The session waits for both: an opinion someone
    holds is never withdrawn because another one was waited for first."""
    hub = bare_team(tmp_path, ["ann", "xav"], 4.0, overlap=0.0, overlap_until=1000)
    tables, result = hub.crowd.tables, {}

    def ask() -> None:
        result["record"] = hub.source("offline", 3).ask_session(team_request("pairwise", 2, 2))[1]

    session = Thread(target=ask)
    session.start()
    for name in ("ann", "xav"):  # each answers their chain's question at once
        question = _claimed(tables, name)
        tables.record_answer(question, _choice(question), 5.0, name)
    ended = time.monotonic()

    def late(name: str, take: float, answer: float) -> None:
        time.sleep(max(0.0, ended + take - time.monotonic()))
        question = tables.claim(name)
        assert question is not None and key_of(question.index) != ChainStep(0, 0)
        time.sleep(max(0.0, ended + answer - time.monotonic()))
        tables.record_answer(question, _choice(question), 5.0, name)

    people = [
        Thread(target=late, args=("xav", 1.0, 4.5)),
        Thread(target=late, args=("ann", 2.0, 5.2)),
    ]
    for person in people:
        person.start()
    session.join(60)
    for person in people:
        person.join(10)
    record = result["record"]
    assert record.crowd is not None and len(record.crowd.second_opinions) == 2
    withdrawn = hub.db.rows("SELECT 1 FROM crowd_questions WHERE withdrawn_at IS NOT NULL")
    assert not withdrawn
    hub.db.close()


def _claimed(tables: CrowdTables, name: str):
    for _ in range(2000):
        question = tables.claim(name)
        if question is not None:
            return question
        time.sleep(0.005)
    raise AssertionError(f"{name} was given no question")


def test_a_session_is_complete_when_its_own_questions_are_answered_not_its_opinions(tmp_path):
    """A team's session stopped after 2 of its 3 questions and 3 other opinions is not
    complete: a rerun asks the third (`run_offline` compares this count with the session's
    questions)."""
    db = LabelDB.in_dir(tmp_path)
    tables = CrowdTables(db)
    pool = Segments(np.zeros((4, 3, 4), np.float32), np.zeros((4, 3)), [None] * 4, [None] * 4)
    db.create_session("offline", 0, "pairwise", 3, 0, "left", pool)
    a, b, c, d = sorted(db.segment_ids("offline", 0).values())
    keys = [ChainStep(0, 0), ChainStep(1, 0)]
    keys += [SecondOpinionOf(ChainStep(0, 0)), SecondOpinionOf(ChainStep(0, 0), 1)]
    keys += [SecondOpinionOf(ChainStep(1, 0))]
    for n, key in enumerate(keys):
        first, second = (a, b) if n % 2 == 0 else (c, d)
        question = db.ensure_question("offline", 0, key.index, first, second, None, first, second)
        who = ("ann", "bob", "carol")[n % 3]
        tables.pose(question, 0 if isinstance(key, ChainStep) else SECOND_OPINIONS, who, None)
        tables.record_answer(question, "left", 5.0, who)
    assert db.count("offline", 0) == 2
    db.close()
