"""What a security probe of the labelling server found (about 170 hostile requests), each
pinned: refusals logged escaped and all of them logged, broadcast addresses not taken for
the machine's own, WebSocket handshakes guarded, an origin's scheme compared."""

from __future__ import annotations

import logging

import pytest
from starlette.testclient import WebSocketDenialResponse
from starlette.websockets import WebSocketDisconnect

from seqrank.labelling.access import Access
from support.pages import page_client, waiting_question_hub

TOKEN = "correct-horse-battery-staple"
ANSWER = {"question_id": 1, "choice": "left", "latency_ms": 5}
ACCESS_LOG = "seqrank.labelling.access"


@pytest.fixture
def hub(tmp_path):
    hub = waiting_question_hub(tmp_path / "labels")
    yield hub
    hub.db.close()


def refusals(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == ACCESS_LOG]


def test_a_refused_paths_control_characters_reach_the_log_escaped(hub, caplog):
    caplog.set_level(logging.WARNING, ACCESS_LOG)
    client = page_client(hub)
    # a newline forging a second log line, and ANSI escapes that clear the terminal
    forged = "/x%0A2026-12-04 WARNING access granted%1B[2J%1B]0;pwned%07"
    assert client.get(forged, headers={"host": "rebind.example"}).status_code == 400
    (line,) = refusals(caplog)
    assert not any(ord(c) < 32 or ord(c) == 127 for c in line)
    assert "\\n2026-12-04 WARNING access granted\\x1b[2J" in line and "(400)" in line


@pytest.mark.parametrize(
    "request_kwargs, status",
    [
        ({"content": "x=1", "headers": {"content-type": "text/plain"}}, 415),
        (
            {
                "content": b"{" + b" " * 70_000 + b"}",
                "headers": {"content-type": "application/json"},
            },
            413,
        ),
    ],
)
def test_bodies_refused_for_their_type_or_size_are_logged_too(hub, caplog, request_kwargs, status):
    caplog.set_level(logging.WARNING, ACCESS_LOG)
    client = page_client(hub)
    assert client.post("/api/answer", **request_kwargs).status_code == status
    (line,) = refusals(caplog)
    assert line.startswith("refused POST /api/answer") and f"({status})" in line


@pytest.mark.parametrize("address", ["255.255.255.255", "127.255.255.255", "127.0.0.0"])
def test_listening_everywhere_broadcast_and_network_addresses_are_not_the_machines_own(
    hub, address
):
    everywhere = Access.serving("0.0.0.0", 8765, TOKEN)
    # (127.0.0.0/8 is every Linux machine's loopback subnet: its edges bind but name no host)
    assert not everywhere.serves(address)
    assert everywhere.serves("127.0.0.2")  # an address of the machine still is
    client = page_client(hub, everywhere)
    reply = client.get("/api/state", headers={"host": f"{address}:8765", "x-seqrank-token": TOKEN})
    assert reply.status_code == 400


def websocket_refusal(client, **headers) -> int:
    """The close code a WebSocket handshake to the page gets (addressed as the page is,
    unless `host` says otherwise: the test client's WebSockets go to "testserver")."""
    headers = {"host": client.base_url.netloc.decode(), **headers}
    try:
        with client.websocket_connect("/api/socket", headers=headers) as socket:
            socket.receive_text()
    except WebSocketDisconnect as closed:
        return closed.code
    except WebSocketDenialResponse as denied:
        return denied.status_code
    raise AssertionError("the handshake was accepted")


def test_websocket_handshakes_pass_the_same_guard(tmp_path, caplog):
    caplog.set_level(logging.WARNING, ACCESS_LOG)
    hub = waiting_question_hub(tmp_path / "labels", token=TOKEN)
    client = page_client(hub)
    assert websocket_refusal(client, host="rebind.example") == 1008  # a rebound name
    assert websocket_refusal(client, origin="http://evil.example") == 1008
    assert websocket_refusal(client) == 1008  # no token
    reasons = [line.split(": ", 1)[1] for line in refusals(caplog)]
    assert [r.split()[0] for r in reasons] == ["Host", "requests", "missing"]
    # with the token the guard lets it through: the page has no WebSocket, so the app's own
    # router refuses it (another close code, and no line of the guard's)
    assert websocket_refusal(client, **{"x-seqrank-token": TOKEN}) != 1008
    assert len(refusals(caplog)) == 3
    hub.db.close()


def test_an_origin_of_another_scheme_is_another_origin(hub):
    client = page_client(hub)
    host = client.base_url.netloc.decode()
    for scheme, status in (("https", 403), ("ftp", 403), ("http", 200)):
        reply = client.post("/api/answer", json=ANSWER, headers={"origin": f"{scheme}://{host}"})
        assert reply.status_code == status, scheme
