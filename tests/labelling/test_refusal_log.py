"""Refusals made by the app itself (issue 45, item 14) are logged as the access guard's are:
one line `refused METHOD PATH (STATUS): reason` on the access log, escaped, and never the
body: an annotator on the operator's endpoints, an answer to somebody else's question, a
body that does not parse."""

from __future__ import annotations

import logging

import pytest

from support.pages import page_client, team_question_for_bob

ACCESS_LOG = "seqrank.labelling.access"
SECRET = "\x1b[2Jsecret-body-text"  # what a body carries: never in the log, not even escaped


@pytest.fixture
def team(tmp_path):
    """alice and bob at a page whose one question (id 1) is posed to bob."""
    hub = team_question_for_bob(tmp_path / "labels")
    yield hub
    hub.db.close()


def client_of(hub, name: str):
    client = page_client(hub)
    client.headers["x-seqrank-token"] = hub.crowd.tokens[name]
    return client


def refusals(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == ACCESS_LOG]


@pytest.mark.parametrize("path", ["/operator", "/api/operator", "/api/labels.jsonl"])
def test_an_annotator_on_the_operators_endpoints_is_logged(team, caplog, path):
    caplog.set_level(logging.WARNING, ACCESS_LOG)
    assert client_of(team, "alice").get(path).status_code == 403
    (line,) = refusals(caplog)
    assert line.startswith(f"refused GET {path} (403): ") and "alice" in line


def test_an_answer_to_somebody_elses_question_is_logged(team, caplog):
    caplog.set_level(logging.WARNING, ACCESS_LOG)
    body = {"question_id": 1, "choice": "left", "latency_ms": 5}
    assert client_of(team, "alice").post("/api/answer", json=body).status_code == 403
    (line,) = refusals(caplog)
    assert line.startswith("refused POST /api/answer (403): question 1 is another annotator's")
    assert "alice" in line
    assert client_of(team, "bob").post("/api/answer", json=body).status_code == 200
    assert len(refusals(caplog)) == 1  # what is taken is not logged


@pytest.mark.parametrize(
    "content",
    [
        '{"question_id": 1, "choice": "' + SECRET,  # not JSON
        '{"question_id": 1, "choice": "' + SECRET.replace("\x1b", "\\u001b") + '", '
        '"latency_ms": 5}',  # JSON, but no choice
        '{"question_id": "' + SECRET.replace("\x1b", "\\u001b") + '", "choice": "left", '
        '"latency_ms": 5}',  # an id that is text
        '{"question_id": 1, "choice": "left", "latency_ms": 5, "'
        + SECRET.replace("\x1b", "\\u001b")
        + '": 1}',  # a field of nobody's
    ],
    ids=["not-json", "bad-choice", "text-id", "extra-field"],
)
def test_a_body_that_does_not_parse_is_logged_without_the_body(team, caplog, content):
    caplog.set_level(logging.WARNING, ACCESS_LOG)
    reply = client_of(team, "bob").post(
        "/api/answer", content=content, headers={"content-type": "application/json"}
    )
    assert reply.status_code == 422
    (line,) = refusals(caplog)
    assert line.startswith("refused POST /api/answer (422): ")
    assert "secret" not in line and "\\x1b" not in line and "\x1b" not in line
    assert not team.db.answered_questions()


def test_an_unknown_question_and_a_conflicting_answer_are_logged_too(team, caplog):
    caplog.set_level(logging.WARNING, ACCESS_LOG)
    bob = client_of(team, "bob")
    body = {"question_id": 1, "choice": "left", "latency_ms": 5}
    assert bob.post("/api/answer", json={**body, "question_id": 99}).status_code == 404
    assert bob.post("/api/answer", json=body).status_code == 200
    assert bob.post("/api/answer", json={**body, "choice": "right"}).status_code == 409
    statuses = [line.split("(", 1)[1].split(")", 1)[0] for line in refusals(caplog)]
    assert statuses == ["404", "409"]


def test_what_a_browser_asks_by_itself_is_no_refusal(team, caplog):
    caplog.set_level(logging.WARNING, ACCESS_LOG)
    alice = client_of(team, "alice")
    assert alice.get("/favicon.ico").status_code == 204  # asked at every page load
    assert alice.get("/api/state").status_code == 200
    assert refusals(caplog) == []
    assert alice.get("/api/nothing-here").status_code == 404  # a path of nothing: logged
    (line,) = refusals(caplog)
    assert line.startswith("refused GET /api/nothing-here (404): ")
