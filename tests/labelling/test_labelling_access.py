"""Who may use the labelling page: tokens, the Host and Origin checks, the session cookie,
and the command line's refusals (the browser's view is in test_labelling_browser.py)."""

from __future__ import annotations

import socket

import httpx
import pytest

from seqrank.cli import main
from seqrank.labelling.access import Access, host_name, page_token
from support.pages import page_client, start_command, waiting_question_hub

TOKEN = "correct-horse-battery-staple"
ANSWER = {"question_id": 1, "choice": "left", "latency_ms": 5}


@pytest.fixture
def hub(tmp_path):
    hub = waiting_question_hub(tmp_path / "labels")
    yield hub
    hub.db.close()


@pytest.fixture
def guarded(tmp_path):
    hub = waiting_question_hub(tmp_path / "labels", token=TOKEN)
    yield hub
    hub.db.close()


def stored(hub) -> int:
    return len(hub.db.answered_questions())


def test_beyond_loopback_a_token_is_always_made_or_long_enough():
    made = page_token("0.0.0.0", None)
    assert made is not None and len(made) >= 22 and made != page_token("0.0.0.0", None)
    assert page_token("127.0.0.1", None) is None and page_token("localhost", None) is None
    assert page_token("::1", "short") == "short"  # loopback: the person's choice
    assert page_token("192.168.1.5", "x" * 16) == "x" * 16
    for host, token in [("0.0.0.0", ""), ("0.0.0.0", "short"), ("::", "a" * 15), ("::1", "")]:
        with pytest.raises(ValueError, match="--token of"):
            page_token(host, token)
    with pytest.raises(ValueError, match="letters, digits"):
        page_token("0.0.0.0", "a/b?c&d=e#f" * 2)


@pytest.mark.parametrize("token", ["", "tooshort"])
def test_the_command_refuses_a_weak_token_beyond_loopback_in_one_line(tmp_path, capsys, token):
    out = tmp_path / "labels"
    args = ["label", "offline", "--task", "dmc:cartpole_swingup", "--out", str(out)]
    assert main([*args, "--host", "0.0.0.0", "--token", token]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and "--token" in error and "at least 16" in error
    assert not out.exists()


def test_host_names_are_parsed_and_only_served_ones_pass():
    assert host_name("127.0.0.1:8765") == "127.0.0.1"
    assert host_name("[::1]:8765") == "::1" and host_name("LocalHost.") == "localhost"
    for malformed in ("", "a:b:c", "[::1", "[::1]x", "host:port"):
        assert host_name(malformed) is None
    loopback = Access.serving("127.0.0.1", 8765, None)
    assert all(loopback.serves(n) for n in ("127.0.0.1", "localhost", "::1"))
    assert not loopback.serves("rebind.example") and not loopback.serves("192.168.1.5")
    everywhere = Access.serving("0.0.0.0", 8765, TOKEN, ["labels.example.org"])
    assert everywhere.serves(socket.gethostname().lower())
    assert everywhere.serves("127.0.0.2")  # any address of this machine
    assert everywhere.serves("labels.example.org")  # named with --allow-host
    assert not everywhere.serves("203.0.113.7") and not everywhere.serves("rebind.example")
    assert not everywhere.serves("0.0.0.0")


@pytest.mark.parametrize("host", ["rebind.example:8765", "192.0.2.1:8765", "a:b:c"])
def test_a_foreign_host_header_is_refused_even_without_a_token(hub, host):
    client = page_client(hub)
    for reply in (
        client.get("/api/state", headers={"host": host}),
        client.post("/api/answer", json=ANSWER, headers={"host": host}),
    ):
        assert reply.status_code == 400 and "not an address this server serves" in reply.text
    assert stored(hub) == 0
    assert client.get("/api/state", headers={"host": "localhost:9000"}).status_code == 200


@pytest.mark.parametrize(
    "headers",
    [
        {"origin": "http://evil.example"},
        {"origin": "http://127.0.0.1:9999"},  # another service on this machine
        {"origin": "null"},
        {"origin": "http://127.0.0.1:8765", "sec-fetch-site": "same-site"},
    ],
)
def test_requests_from_another_origin_neither_write_nor_read(hub, headers):
    client = page_client(hub)
    assert client.post("/api/answer", json=ANSWER, headers=headers).status_code == 403
    assert client.get("/api/state", headers=headers).status_code == 403
    assert stored(hub) == 0


def test_the_page_itself_and_clients_without_origin_may_write(hub):
    client = page_client(hub)
    own = {"origin": "http://127.0.0.1:8765", "sec-fetch-site": "same-origin"}
    assert client.post("/api/answer", json=ANSWER, headers=own).status_code == 200
    assert client.post("/api/answer", json=ANSWER).json()["duplicate"] is True  # curl, scripts
    assert stored(hub) == 1


def test_a_link_from_elsewhere_may_open_the_page_but_not_embed_it(hub):
    client = page_client(hub)
    link = {"sec-fetch-site": "cross-site", "sec-fetch-mode": "navigate"}
    assert client.get("/", headers={**link, "sec-fetch-dest": "document"}).status_code == 200
    assert client.get("/", headers={**link, "sec-fetch-dest": "iframe"}).status_code == 403
    headers = client.get("/").headers
    assert "frame-ancestors 'none'" in headers["content-security-policy"]
    assert headers["x-frame-options"] == "DENY" and headers["referrer-policy"] == "no-referrer"


def test_a_form_posted_from_elsewhere_is_not_json_and_is_refused(hub):
    # the classic CSRF: a text/plain form whose body happens to read as JSON
    client = page_client(hub)
    body = '{"question_id": 1, "choice": "left", "latency_ms": 5, "x": "="}'
    reply = client.post("/api/answer", content=body, headers={"content-type": "text/plain"})
    assert reply.status_code == 415 and stored(hub) == 0


def test_the_token_from_the_address_is_traded_for_a_hardened_cookie(guarded):
    access = Access.serving("127.0.0.1", 8765, TOKEN)
    client = page_client(guarded, access)
    assert client.get("/").status_code == 401
    assert client.get("/?token=wrong").status_code == 401
    assert client.get(f"/api/state?token={TOKEN}").status_code == 401  # the page address only
    page = client.get(f"/?token={TOKEN}")
    assert page.status_code == 200
    cookie = page.headers["set-cookie"]
    name, _, rest = cookie.partition("=")
    assert name == "seqrank_session_8765" and TOKEN not in cookie
    assert {"HttpOnly", "SameSite=Strict", "Path=/"} <= {p.strip() for p in rest.split(";")}
    state = client.get("/api/state")  # the cookie alone
    assert state.status_code == 200
    clip = state.json()["question"]["left"]["clip"]
    assert "token" not in clip and client.get(clip).status_code == 404  # guarded, no states
    assert client.post("/api/answer", json=ANSWER).status_code == 200
    other_port = page_client(guarded, Access.serving("127.0.0.1", 8766, TOKEN))
    other_port.cookies.set("seqrank_session_8765", client.cookies["seqrank_session_8765"])
    assert other_port.get("/api/state").status_code == 401  # each server its own cookie


def test_scripts_carry_the_token_in_a_header(guarded):
    client = page_client(guarded, Access.serving("127.0.0.1", 8765, TOKEN))
    assert client.get("/api/state", headers={"x-seqrank-token": TOKEN}).status_code == 200
    assert client.get("/api/state", headers={"x-seqrank-token": TOKEN[:-1]}).status_code == 401
    assert client.get("/api/labels.jsonl").status_code == 401
    assert client.get("/static/app.js").status_code == 401


def test_listening_everywhere_prints_a_tokened_address_and_guards_every_request(tmp_path):
    command = ["label", "offline", "--task", "dmc:cartpole_swingup", "--episodes", "1"]
    where = ["--host", "0.0.0.0", "--port", "0", "--out", str(tmp_path / "labels")]
    process, url = start_command([*command, *where])
    try:
        address, _, token = url.partition("/?token=")
        assert len(token) >= 22 and address.startswith("http://127.0.0.1:")
        assert httpx.get(f"{address}/api/state").status_code == 401
        assert httpx.get(f"{address}/api/state?token={token}").status_code == 401
        reply = httpx.get(f"{address}/api/state", headers={"x-seqrank-token": token})
        assert reply.status_code == 200
        port = address.rsplit(":", 1)[1]
        rebound = httpx.get(
            f"{address}/api/state",
            headers={"x-seqrank-token": token, "host": f"rebind.example:{port}"},
        )
        assert rebound.status_code == 400
    finally:
        process.kill()
        process.wait(10)
