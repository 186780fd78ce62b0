"""The page's random streams and keys keep the numbers stored sessions were made with
(issue 48, item 3): a replay after the move draws what the first run drew, and a session
asks what it asked before."""

from __future__ import annotations

import threading
import time
from threading import Event

import numpy as np
import pytest

from seqrank.labelling.crowd_keys import ChainStep, SecondOpinionOf, key_of
from seqrank.labelling.db import LabelDB
from seqrank.labelling.human import Hub, PageSettings
from seqrank.labelling.streams import (
    Stream,
    one_person_draws,
    one_person_side,
    session_seed,
    stream,
)
from support.crowd import bare_team, team_request

# the numbers each stream was drawn with before it was named
BEFORE = {
    Stream.ROLLOUT: 3,
    Stream.OFFLINE_SESSION: 4,
    Stream.CHAIN: 7,
    Stream.CHAIN_DEFENDER_SIDE: 8,
    Stream.SECOND_OPINION: 9,
    Stream.QUESTION_SIDE: 10,
    Stream.GOLD: 11,  # (named from the start)
    Stream.GOLD_ORDER: 12,
}


@pytest.mark.parametrize(("name", "number"), BEFORE.items())
def test_a_named_stream_draws_what_its_number_drew(name, number):
    for seed, keys in [(0, ()), (12345, (2,)), (2**40 + 7, (100_003,))]:
        old = np.random.default_rng([seed, number, *keys]).random(4)
        assert np.array_equal(stream(seed, name, *keys).random(4), old)


def test_the_streams_are_distinct_and_every_one_is_pinned():
    assert set(BEFORE) == set(Stream)
    assert len({int(s) for s in Stream}) == len(Stream)


def test_a_session_seed_and_one_persons_draws_are_as_stored():
    seed = session_seed(3, "online", 2)
    assert seed == int(np.random.SeedSequence([3, 2, *b"online"]).generate_state(1)[0])
    assert seed == 2847668404  # a stored session's seed, worked out once
    assert one_person_draws(seed).random() == np.random.default_rng(seed).random()
    assert one_person_side(seed, 5).random() == np.random.default_rng([seed, 5]).random()


def test_keys_encode_as_stored_sessions_hold_them():
    assert ChainStep(0, 0).index == 0
    assert ChainStep(2, 7).index == 200_007
    assert SecondOpinionOf(ChainStep(2, 7)).index == -200_008
    assert SecondOpinionOf(ChainStep(0, 0)).index == -1
    for index in (0, 5, 100_000, 300_042, -1, -6, -100_001, -300_043):
        assert key_of(index).index == index
    with pytest.raises(ValueError):
        ChainStep(0, 100_000)


# (index, first, second, left, right) of each question, as the code before the move
# (83db08d) stored them for the sessions below: answers a function of the question
TEAM_QUESTIONS = [
    (-100003, 13, 9, 9, 13), (-100001, 17, 14, 17, 14), (-3, 2, 1, 2, 1), (-2, 4, 2, 4, 2),
    (-1, 3, 4, 4, 3), (0, 3, 4, 4, 3), (1, 4, 2, 2, 4), (2, 2, 1, 1, 2),
    (100000, 17, 14, 14, 17), (100001, 14, 13, 13, 14), (100002, 13, 9, 9, 13),
]  # fmt: skip
SOLO_QUESTIONS = [
    (0, 11, 3, 11, 3), (1, 11, 7, 11, 7), (2, 11, 14, 11, 14), (3, 14, 2, 14, 2),
    (4, 2, 5, 2, 5), (5, 5, 6, 5, 6),
]  # fmt: skip


def _choice(question) -> str:
    return ("left", "right", "equal")[(question.left * 7 + question.right) % 3]


def _answering(answer_one, done: threading.Event) -> None:
    def run() -> None:
        while not done.is_set():
            if not answer_one():
                time.sleep(0.005)

    threading.Thread(target=run, daemon=True).start()


def _questions(db: LabelDB) -> list[tuple]:
    sql = "SELECT idx, first, second, left_seg, right_seg FROM questions ORDER BY idx"
    return [tuple(row) for row in db.rows(sql)]


def test_a_team_and_a_person_ask_what_they_asked_before_the_move(tmp_path):
    hub, done = bare_team(tmp_path / "team", ["alice", "bob"], 60.0, overlap=0.5), Event()
    tables = hub.crowd.tables
    for name in ("alice", "bob"):

        def one(name: str = name) -> bool:
            question = tables.claim(name)
            return question is not None and bool(
                tables.record_answer(question, _choice(question), 5.0, name)
            )

        _answering(one, done)
    hub.source("offline", 11).ask_session(team_request("sequential", 6, 2, spare=2))
    done.set()
    assert _questions(hub.db) == TEAM_QUESTIONS  # second opinions, chains' questions, sides
    hub.db.close()

    solo, done = Hub(LabelDB.in_dir(tmp_path / "solo"), PageSettings(0.0, "p", None)), Event()

    def answer() -> bool:
        question = solo.db.pending_question()
        return question is not None and bool(
            solo.db.record_answer(question, _choice(question), 5.0, "p")
        )

    _answering(answer, done)
    solo.source("online", 11).ask_session(team_request("root", 6, 1, spare=2))
    done.set()
    assert _questions(solo.db) == SOLO_QUESTIONS
    solo.db.close()
