"""Whose request it is when it carries two credentials (issue 45, item 11): the token in
the address wins over the session cookie, a header's token wins over the cookie, the cookie
is then re-issued for the winner, and an address and a header naming two tokens are
refused. Never a matter of the order the team was listed in."""

from __future__ import annotations

import pytest

from support.pages import page_client, team_question_for_bob

COOKIE = "seqrank_session_0"  # the test app's (a loopback access on port 0)
NOBODY = "x" * 24


@pytest.fixture
def team(tmp_path):
    """alice and bob at a page whose one question (id 1) is posed to bob."""
    hub = team_question_for_bob(tmp_path / "labels")
    yield hub
    hub.db.close()


def tokens(hub) -> dict[str, str]:
    return {**hub.crowd.tokens, "operator": hub.crowd.operator_token}


def who(reply) -> str:
    assert reply.status_code == 200, reply.text
    return reply.json()["annotator"]


def browser_of(hub, name: str):
    """A browser that opened `name`'s link: it holds `name`'s session cookie."""
    client = page_client(hub)
    assert client.get(f"/?token={tokens(hub)[name]}").status_code == 200
    assert COOKIE in client.cookies and who(client.get("/api/state")) == name
    return client


@pytest.mark.parametrize(("first", "then"), [("alice", "bob"), ("bob", "alice")])
def test_a_link_opened_in_a_browser_with_anothers_cookie_is_the_links_person(team, first, then):
    client = browser_of(team, first)
    held = client.cookies[COOKIE]
    opened = client.get(f"/?token={tokens(team)[then]}")
    assert opened.status_code == 200 and COOKIE in opened.headers.get("set-cookie", "")
    assert client.cookies[COOKIE] != held  # the cookie is re-issued for the link's person
    assert who(client.get("/api/state")) == then  # the cookie alone now says so


def test_a_header_token_beside_anothers_cookie_acts_as_the_headers_person(team):
    client = browser_of(team, "alice")
    bob = {"x-seqrank-token": tokens(team)["bob"]}
    reply = client.get("/api/state", headers=bob)
    assert who(reply) == "bob" and COOKIE in reply.headers.get("set-cookie", "")
    assert who(client.get("/api/state")) == "bob"  # re-issued: the cookie is bob's now
    again = client.get("/api/state", headers=bob)  # the cookie's own holder: nothing to re-issue
    assert who(again) == "bob" and "set-cookie" not in again.headers
    # bob's answer, sent from alice's browser with his token, is stored as his
    alice_browser = browser_of(team, "alice")
    body = {"question_id": 1, "choice": "left", "latency_ms": 5}
    assert alice_browser.post("/api/answer", json=body).status_code == 403  # not alice's
    assert alice_browser.post("/api/answer", json=body, headers=bob).status_code == 200
    assert [a.annotator for _, a in team.db.answered_questions()] == ["bob"]


def test_an_address_and_a_header_naming_two_tokens_are_refused(team):
    client = page_client(team)
    mixed = client.get(f"/?token={tokens(team)['alice']}", headers={"x-seqrank-token": NOBODY})
    assert mixed.status_code == 400 and "two different tokens" in mixed.json()["detail"]
    assert "set-cookie" not in mixed.headers
    both = client.get(
        f"/operator?token={tokens(team)['operator']}",
        headers={"x-seqrank-token": tokens(team)["bob"]},
    )
    assert both.status_code == 400
    same = {"x-seqrank-token": tokens(team)["alice"]}  # one token twice is one person
    assert client.get(f"/?token={tokens(team)['alice']}", headers=same).status_code == 200


def test_a_wrong_token_is_refused_even_beside_a_good_cookie(team):
    client = browser_of(team, "alice")
    assert client.get(f"/?token={NOBODY}").status_code == 401
    assert client.get("/api/state", headers={"x-seqrank-token": NOBODY}).status_code == 401
    assert who(client.get("/api/state")) == "alice"  # the cookie is still alice's
    # a token in the address of anything but a page is not a credential, as before
    assert who(client.get(f"/api/state?token={tokens(team)['bob']}")) == "alice"
