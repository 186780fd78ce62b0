"""Every bad request gets a 4xx JSON error, never a 500, and stores nothing.

Hypothesis throws generated requests at every endpoint through the whole middleware stack:
bodies built from the schemas and stretched past their limits (huge and negative integers,
NaN and infinities, lone surrogates, long strings, wrong types, extra keys), garbage bytes,
other content types and methods, paths with generated ids and names, and now and then a
generated Host or Origin. Derandomized with a fixed number of examples, so CI sees the
same requests every run (about 10 s on 2 cores).
"""

from __future__ import annotations

import json
import sqlite3
from urllib.parse import quote

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from support.pages import page_client, waiting_question_hub

FUZZ = settings(
    max_examples=400,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=list(HealthCheck),
)
TABLES = ("sessions", "segments", "questions", "answers", "surveys", "choices", "meta")

edge_integers = st.sampled_from([0, 1, -1, 2**31, 2**53 - 1, 2**53, 2**63 - 1, 2**63, 2**64])
integers = st.one_of(st.integers(-(2**70), 2**70), edge_integers)
floats = st.one_of(st.floats(), integers)
# lone surrogates included: JSON's \ud800 escapes make them
texts = st.text(st.characters(exclude_categories=()), max_size=30)
long_texts = st.integers(0, 7000).map(lambda n: "é" * n)
json_values = st.recursive(
    st.none() | st.booleans() | integers | floats | texts,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(texts, inner, max_size=3),
    max_leaves=6,
)


def shaped(fields: dict[str, st.SearchStrategy]) -> st.SearchStrategy:
    """Bodies shaped like a schema: its fields (any may be missing), now and then one more."""
    near = {key: strategy | json_values for key, strategy in fields.items()}
    return st.one_of(
        st.fixed_dictionaries(near, optional={"extra": json_values}),
        st.fixed_dictionaries({}, optional=near),
    )


answers = shaped(
    {
        "question_id": integers,
        "choice": st.sampled_from(["left", "right", "equal", "skip", "timeout"]) | texts,
        "latency_ms": floats,
    }
)
surveys = shaped(
    {"run": st.just("offline") | texts | long_texts, "satisfaction": integers, "criteria": texts}
)


@st.composite
def bodies(draw: st.DrawFn) -> bytes:
    kind = draw(st.sampled_from(["answer", "survey", "json", "garbage", "broken"]))
    if kind == "garbage":
        return draw(st.binary(max_size=200))
    value = draw({"answer": answers, "survey": surveys}.get(kind, json_values))
    encoded = json.dumps(value, allow_nan=True).encode()  # NaN and Infinity as literals
    if kind == "broken":  # a byte cut out or replaced: invalid JSON or invalid UTF-8
        at = draw(st.integers(0, len(encoded)))
        encoded = encoded[:at] + draw(st.binary(max_size=2)) + encoded[at + 1 :]
    return encoded


def path_part(text: str) -> str:
    return quote(text, safe="", errors="surrogatepass")


paths = st.one_of(
    st.sampled_from(["/", "/api/state", "/api/answer", "/api/survey", "/api/labels.jsonl"]),
    st.sampled_from(["/static/app.js", "/static/index.html", "/static/../labels.sqlite"]),
    integers.map(lambda n: f"/api/clips/{n}.mp4"),
    texts.map(lambda t: f"/api/clips/{path_part(t)}.mp4"),
    texts.map(lambda t: f"/static/{path_part(t)}"),
    texts.map(lambda t: f"/{path_part(t)}"),
)
methods = st.sampled_from(["GET", "POST", "POST", "POST", "PUT", "DELETE", "PATCH", "HEAD"])
content_types = st.sampled_from(
    ["application/json"] * 4 + ["application/json; charset=latin-1", "text/plain", ""]
)
header_values = st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=40)
odd_headers = st.fixed_dictionaries(
    {}, optional={"host": header_values, "origin": header_values, "content-length": header_values}
)
headers = st.one_of(st.just({}), st.just({}), st.just({}), odd_headers)


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    hub = waiting_question_hub(tmp_path_factory.mktemp("fuzz") / "labels")
    hub.state.open_survey("offline", "pairwise", "survey")  # a survey is open too
    yield hub, page_client(hub)
    hub.db.close()


def rows(hub) -> dict[str, int]:
    return {t: hub.db._rows(f"SELECT COUNT(*) AS n FROM {t}")[0]["n"] for t in TABLES}


def check_reply(reply, method: str) -> None:
    assert reply.status_code < 500, (reply.status_code, reply.text[:300])
    if reply.status_code >= 400 and method != "HEAD":
        detail = reply.json()["detail"]
        assert isinstance(detail, str) and len(reply.content) < 4096


@FUZZ
@given(method=methods, path=paths, body=bodies(), content_type=content_types, extra=headers)
def test_generated_requests_never_fail_the_server_nor_store_when_refused(
    page, method, path, body, content_type, extra
):
    hub, client = page
    before = rows(hub)
    sent = {"content-type": content_type, **extra} if content_type else extra
    reply = client.request(method, path, content=body, headers=sent)
    check_reply(reply, method)
    if reply.status_code >= 400:
        assert rows(hub) == before


@pytest.fixture
def hub(tmp_path):
    hub = waiting_question_hub(tmp_path / "labels")
    hub.state.open_survey("offline", "pairwise", "survey")
    yield hub
    hub.db.close()


@pytest.mark.parametrize(
    ("path", "body"),
    [
        ("/api/answer", b'{"question_id": 9223372036854775808, "choice": "left", "latency_ms": 1}'),
        ("/api/answer", b'{"question_id": 1, "choice": "left", "latency_ms": NaN}'),
        ("/api/answer", b'{"question_id": 1, "choice": "left", "latency_ms": Infinity}'),
        ("/api/answer", b'{"question_id": true, "choice": "left", "latency_ms": 1}'),
        ("/api/answer", b'{"question_id": 1, "choice": "left", "latency_ms": 1e400}'),
        ("/api/survey", b'{"run": "\\ud800", "satisfaction": 3, "criteria": ""}'),
        ("/api/survey", b'{"run": "offline", "satisfaction": 3, "criteria": "\\udfff"}'),
        ("/api/survey", b'{"run": "off\\u0000line", "satisfaction": 3, "criteria": ""}'),
        ("/api/survey", b'{"run": "offline", "satisfaction": 3, "criteria": "\xff\xfe"}'),
        ("/api/survey", b'{"run": "offline", "satisfaction": 3.0, "criteria": ""}'),
        ("/api/survey", b'{"\\ud800": 1}'),
    ],
)
def test_the_inputs_that_used_to_give_500_get_4xx_json(hub, path, body):
    client = page_client(hub)
    reply = client.post(path, content=body, headers={"content-type": "application/json"})
    assert 400 <= reply.status_code < 500 and isinstance(reply.json()["detail"], str)
    assert rows(hub)["answers"] == rows(hub)["surveys"] == 0


@pytest.mark.parametrize("segment", ["18446744073709551616", "-1", "0", "1e3", "%00"])
def test_path_ids_out_of_range_get_422(hub, segment):
    reply = page_client(hub).get(f"/api/clips/{segment}.mp4")
    assert reply.status_code == 422 and "segment_id" in reply.json()["detail"]


def test_a_big_body_is_refused_before_parsing_and_never_echoed(hub):
    client = page_client(hub)
    big = b'{"run": "' + b"x" * 10_000_000 + b'"}'
    reply = client.post("/api/survey", content=big, headers={"content-type": "application/json"})
    assert reply.status_code == 413 and len(reply.content) < 300

    def chunks():  # no Content-Length: counted while it arrives
        for _ in range(100):
            yield b"x" * 10_000

    reply = client.post(
        "/api/answer", content=chunks(), headers={"content-type": "application/json"}
    )
    assert reply.status_code == 413 and len(reply.content) < 300
    assert rows(hub)["answers"] == rows(hub)["surveys"] == 0


def test_validation_errors_name_the_field_and_the_rule_but_not_the_value(hub):
    body = {"run": "offline", "satisfaction": 3, "criteria": "secret " * 1000}
    reply = page_client(hub).post("/api/survey", json=body)
    assert reply.status_code == 422 and "secret" not in reply.text and len(reply.content) < 1000
    assert reply.json()["detail"] == "body.criteria: String should have at most 5000 characters"
    assert reply.json()["errors"][0]["loc"] == ["body", "criteria"]


def test_a_busy_database_gets_503_with_retry_after(hub, monkeypatch):
    def locked(question_id):
        raise sqlite3.OperationalError("database is locked")

    monkeypatch.setattr(hub.db, "question", locked)
    body = {"question_id": 1, "choice": "left", "latency_ms": 5}
    reply = page_client(hub).post("/api/answer", json=body)
    assert reply.status_code == 503 and reply.headers["retry-after"] == "1"
    assert "database is locked" in reply.json()["detail"]
