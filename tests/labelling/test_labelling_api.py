"""The labelling page's HTTP API, with an offline session driven in a background thread."""

from __future__ import annotations

import io
from concurrent.futures import ThreadPoolExecutor

import av
import pytest

from seqrank.feedback.label_file import parse_lines
from seqrank.labelling import CLIP_SIZE
from seqrank.labelling.app import _recheck
from support.pages import Page

TASK = "dmc:cartpole_swingup"


@pytest.fixture
def page(tmp_path):
    page = Page(tmp_path / "labels", "sequential", 4)
    yield page
    page.close()


def test_state_shows_the_question_with_progress_and_a_fixed_defender_side(page):
    sides = []
    for k in range(4):
        question = page.question()
        assert (question["index"], question["questions"], question["session"]) == (k + 1, 4, 1)
        roles = {question["left"]["role"], question["right"]["role"]}
        assert roles == {"defender", "challenger"}
        sides.append("left" if question["left"]["role"] == "defender" else "right")
        reply = page.client.post(
            "/api/answer", json={"question_id": question["id"], "choice": "right", "latency_ms": 1}
        )
        assert reply.status_code == 200
    assert len(set(sides)) == 1  # the defender never changes side
    page.done.wait(10)
    assert page.state()["status"] == "done"


def test_answers_are_stored_exactly_and_mapped_back_to_the_question_order(page):
    given = []
    for choice in ("left", "right", "equal", "timeout"):
        question, reply = page.answer(choice, latency=321.5)
        assert reply.status_code == 200 and reply.json()["accepted"]
        given.append((question, choice))
    page.done.wait(10)
    stored = page.hub.db.answered_questions()
    assert len(stored) == 4
    for (question, choice), (q, a) in zip(given, stored, strict=True):
        assert q.id == question["id"] and a.choice == choice and a.latency_ms == 321.5
        assert a.annotator == "tester"
        if choice in ("left", "right"):
            preferred = question[choice]["segment"]
            assert a.answer == ("first" if preferred == q.first else "second")
        else:
            assert a.answer == {"equal": "equal", "timeout": "skip"}[choice]
    # the chain moves on: each challenger defends the next question
    assert [q.first for q, _ in stored[1:]] == [q.second for q, _ in stored[:-1]]


def test_duplicates_are_idempotent_and_conflicts_stale_and_unknown_are_rejected(page):
    question, first = page.answer("left")
    assert first.json()["duplicate"] is False
    body = {"question_id": question["id"], "choice": "left", "latency_ms": 9}
    again = page.client.post("/api/answer", json=body)
    assert again.status_code == 200 and again.json()["duplicate"] is True
    conflict = page.client.post("/api/answer", json={**body, "choice": "right"})
    assert conflict.status_code == 409 and "already answered" in conflict.json()["detail"]
    unknown = page.client.post("/api/answer", json={**body, "question_id": 999})
    assert unknown.status_code == 404 and "unknown question 999" in unknown.json()["detail"]
    assert len(page.hub.db.answered_questions()) == 1
    assert page.hub.db.answer(question["id"]).choice == "left"


@pytest.mark.parametrize(
    "body",
    [
        b"not json",
        b"[]",
        b'{"choice": "left", "latency_ms": 1}',
        b'{"question_id": 1, "choice": "up", "latency_ms": 1}',
        b'{"question_id": 1, "choice": "left", "latency_ms": -5}',
        b'{"question_id": "one", "choice": "left", "latency_ms": 1}',
        b'{"question_id": 1, "choice": "left", "latency_ms": 1, "extra": 2}',
    ],
)
def test_malformed_answers_get_4xx_json_and_store_nothing(page, body):
    page.question()
    reply = page.client.post(
        "/api/answer", content=body, headers={"content-type": "application/json"}
    )
    assert 400 <= reply.status_code < 500
    assert "detail" in reply.json()
    assert page.hub.db.answered_questions() == []
    assert page.client.get("/api/state").json()["status"] == "question"


def test_concurrent_submissions_store_one_answer(page):
    question = page.question()
    body = {"question_id": question["id"], "choice": "left", "latency_ms": 3}
    with ThreadPoolExecutor(8) as pool:
        replies = list(pool.map(lambda _: page.client.post("/api/answer", json=body), range(16)))
    assert all(r.status_code == 200 for r in replies)
    assert sum(not r.json()["duplicate"] for r in replies) == 1
    question = page.question()
    choices = ["left", "right", "equal", "skip"] * 4
    with ThreadPoolExecutor(8) as pool:
        replies = list(
            pool.map(
                lambda c: page.client.post(
                    "/api/answer",
                    json={"question_id": question["id"], "choice": c, "latency_ms": 1},
                ),
                choices,
            )
        )
    accepted = [c for c, r in zip(choices, replies, strict=True) if r.status_code == 200]
    assert {r.status_code for r in replies} <= {200, 409}
    assert len(set(accepted)) == 1
    assert page.hub.db.answer(question["id"]).choice == accepted[0]
    assert len(page.hub.db.answered_questions()) == 2


def test_clips_are_h264_mp4_of_the_whole_segment(page):
    question = page.question()
    reply = page.client.get(question["left"]["clip"])
    assert reply.status_code == 200 and reply.headers["content-type"] == "video/mp4"
    with av.open(io.BytesIO(reply.content)) as container:
        stream = container.streams.video[0]
        assert stream.codec_context.name == "h264"
        frames = list(container.decode(stream))
    assert len(frames) == 50 and (frames[0].width, frames[0].height) == (CLIP_SIZE, CLIP_SIZE)
    assert page.client.get("/api/clips/99999.mp4").status_code == 404
    assert page.client.get("/api/clips/abc.mp4").status_code == 422


def test_survey_only_when_open_and_idempotent(page):
    body = {"run": "sequential", "satisfaction": 4, "criteria": "distance moved"}
    assert page.client.post("/api/survey", json=body).status_code == 409
    assert page.client.post("/api/survey", json={**body, "satisfaction": 6}).status_code == 422
    page.hub.state.open_survey("sequential", "sequential", "survey")
    first = page.client.post("/api/survey", json=body)
    assert first.status_code == 200 and first.json()["duplicate"] is False
    assert page.client.post("/api/survey", json=body).json()["duplicate"] is True
    row = page.hub.db.survey("sequential")
    assert (row["satisfaction"], row["criteria"], row["annotator"]) == (
        4,
        "distance moved",
        "tester",
    )


def test_labels_endpoint_exports_what_was_answered(page):
    for choice in ("left", "skip"):
        page.answer(choice)
    text = page.client.get("/api/labels.jsonl").text
    labels = parse_lines(text.splitlines())
    assert labels.header["task"] == TASK and labels.header["obs_dim"] == 5
    assert [a["answer"] for a in labels.answers] == [
        a.answer for _, a in page.hub.db.answered_questions()
    ]
    assert all(labels.segments[a["first"]]["states"] for a in labels.answers)


def test_page_and_static_files_are_served(page):
    html = page.client.get("/")
    assert html.status_code == 200 and "/static/app.js" in html.text
    assert page.client.get("/static/app.js").status_code == 200
    assert page.client.get("/nothing").status_code == 404


def test_pairwise_questions_have_no_roles(tmp_path):
    page = Page(tmp_path / "labels", "pairwise", 2)
    try:
        question = page.question()
        assert question["left"]["role"] is None and question["right"]["role"] is None
    finally:
        page.close()


def test_a_checked_session_shows_a_winning_challenger_again(tmp_path):
    # root, noise-aware: the second challenger's win would put it above the first one's
    # loser, so the same two clips come back; the person agrees, and the root moves on
    page = Page(tmp_path / "labels", "root", 4, augment="checked")
    try:
        shown = []
        for _ in range(4):
            question = page.question()
            challenger = "left" if question["left"]["role"] == "challenger" else "right"
            defender = "right" if challenger == "left" else "left"
            wins = len(shown) in (1, 2)  # the 2nd question and its repeat
            choice = challenger if wins else defender
            _, reply = page.answer(choice)
            assert reply.status_code == 200
            shown.append({question["left"]["segment"], question["right"]["segment"]})
        page.done.wait(10)
        assert shown[1] == shown[2] and shown[0] != shown[1] and shown[2] != shown[3]
        assert len(page.hub.db.answered_questions()) == 4
        assert not _recheck(page.hub.db, 1).contradicted  # the repeat agreed
    finally:
        page.close()


def test_a_repeat_the_person_contradicts_makes_the_next_sessions_ask_twice_more(tmp_path):
    # root, checked, two sessions of 8. Session 0: the second challenger wins (it would
    # imply a pair), its repeat is answered the other way: a contradiction. Session 1: the
    # root beats 5 challengers, then the 6th wins, which would imply 5 pairs: shown three
    # times (a person who never contradicted themselves would see it twice)
    page = Page(tmp_path / "labels", "root", 8, augment="checked", sessions=2)
    try:
        winners = {0: (1,), 1: (5, 6, 7)}  # per session, which questions the challenger wins
        shown = []
        for k in range(16):
            question = page.question()
            role = "challenger" if k % 8 in winners[k // 8] else "defender"
            side = "left" if question["left"]["role"] == role else "right"
            assert page.answer(side)[1].status_code == 200
            shown.append(frozenset((question["left"]["segment"], question["right"]["segment"])))
        page.done.wait(10)
        assert shown[1] == shown[2] and len(set(shown[:8])) == 7  # session 0's repeat
        assert shown[13] == shown[14] == shown[15]  # session 1: asked twice more
        assert _recheck(page.hub.db, 1).contradicted
        assert not _recheck(page.hub.db, 0).contradicted  # a resumed session 0 does not know
    finally:
        page.close()
