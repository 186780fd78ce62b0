"""What a request may carry, and a 4xx JSON error for anything else (never a 500).

- Writes carry JSON (415 otherwise) of at most `MAX_BODY_BYTES`, refused before parsing
  (413) and never echoed back.
- Fields: ids within what a browser's JSON keeps exactly (well inside SQLite's 64-bit
  integers), finite floats, bounded strings of valid unicode (the schemas in `server.py`
  use the types below).
- A validation error names the field and the rule, never the value: FastAPI's default
  echoes the input, a rejected 10 MB body whole, and fails (500) on input that is not
  valid unicode or JSON-encodable.
- A busy database answers 503 with Retry-After, which the page retries.
- Every refusal, of these rules or of a route (an annotator on the operator's endpoints,
  an answer to somebody else's question, a body that does not parse), is logged as the
  access guard's are (`access.log_refusal`): method, path, status and reason, escaped,
  never the body.
"""

from __future__ import annotations

import sqlite3
import unicodedata
from typing import Annotated, Any

from fastapi import FastAPI, Request
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from pydantic import Field
from starlette.datastructures import Headers
from starlette.exceptions import HTTPException
from starlette.responses import JSONResponse, Response
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from seqrank.labelling.access import OPERATOR, SAFE_METHODS, log_refusal

MAX_BODY_BYTES = 64 * 1024
MAX_ID = 2**53 - 1  # the largest integer JavaScript's numbers hold exactly
MAX_PROBLEMS = 5


def valid_unicode(value: str) -> str:
    """Text that encodes as UTF-8 (JSON's \\ud800 escapes make lone surrogates)."""
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        raise ValueError("text must be valid unicode (no lone surrogates)") from None
    return value


def one_line(value: str) -> str:
    """Valid unicode without control characters: a name shown in messages and files."""
    valid_unicode(value)
    if any(unicodedata.category(character) == "Cc" for character in value):
        raise ValueError("control characters are not allowed")
    return value


RowId = Annotated[int, Field(ge=1, le=MAX_ID)]  # a stored row (question, segment)


class BodyRules:
    """ASGI middleware: a write must be JSON within `limit` bytes, checked before any parsing."""

    def __init__(self, app: ASGIApp, limit: int = MAX_BODY_BYTES):
        self.app, self.limit = app, limit

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] in SAFE_METHODS:
            await self.app(scope, receive, send)
            return
        refusal = self._header_refusal(Headers(scope=scope))
        if refusal is not None:
            await self._refuse(refusal, scope, receive, send)
            return
        body = bytearray()
        more = True
        while more:
            message = await receive()
            if message["type"] == "http.disconnect":
                return  # the client has gone: nobody to answer
            body += message.get("body", b"")
            if len(body) > self.limit:
                await self._refuse(self._too_large(), scope, receive, send)
                return
            more = message.get("more_body", False)
        await self.app(scope, _replay(bytes(body), receive), send)

    @staticmethod
    async def _refuse(refusal: tuple[int, str], scope: Scope, receive: Receive, send: Send) -> None:
        """Refusals are logged as the access guard's are (SECURITY.md)."""
        status, detail = refusal
        log_refusal(scope["method"], scope["path"], status, detail)
        await error(status, detail)(scope, receive, send)

    def _header_refusal(self, headers: Headers) -> tuple[int, str] | None:
        media_type = headers.get("content-type", "").partition(";")[0].strip().lower()
        if media_type != "application/json":
            return 415, "send the body as JSON, with Content-Type: application/json"
        length = headers.get("content-length")
        if length is not None and not length.isdigit():
            return 400, "Content-Length must be a number of bytes"
        if length is not None and int(length) > self.limit:
            return self._too_large()
        return None

    def _too_large(self) -> tuple[int, str]:
        return 413, f"the body is larger than {self.limit} bytes"


def _replay(body: bytes, receive: Receive) -> Receive:
    """A `receive` that hands over the body already read, then waits as the original does."""
    sent = False

    async def replay() -> Message:
        nonlocal sent
        if sent:
            return await receive()
        sent = True
        return {"type": "http.request", "body": body, "more_body": False}

    return replay


def error(status: int, detail: str, **extra: Any) -> JSONResponse:
    return JSONResponse({"detail": detail, **extra}, status)


def _printable(value: object, limit: int) -> str:
    """A piece of an error message: valid unicode, at most `limit` characters."""
    text = str(value).encode("utf-8", "backslashreplace").decode("utf-8")
    return text if len(text) <= limit else text[: limit - 1] + "…"


async def _invalid_request(request: Request, problem: Exception) -> JSONResponse:
    assert isinstance(problem, RequestValidationError)
    problems = [
        {
            "loc": [_printable(part, 60) for part in item.get("loc", ())],
            "msg": _printable(item.get("msg", "invalid"), 200),
            "type": _printable(item.get("type", "invalid"), 60),
        }
        for item in problem.errors()[:MAX_PROBLEMS]
    ]
    detail = "; ".join(f"{'.'.join(p['loc'])}: {p['msg']}" for p in problems)
    _log_refusal(request, 422, _unechoed(problem) or "invalid request")
    return error(422, detail or "invalid request", errors=problems)


def _unechoed(problem: RequestValidationError) -> str:
    """A validation error for the log: the field and the rule's name (`literal_error`,
    `json_invalid`), never a value, nor a key that came with the body (an extra field's)."""
    shown = []
    for item in problem.errors()[:MAX_PROBLEMS]:
        loc = [str(part) for part in item.get("loc", ())]
        kind = str(item.get("type", "invalid"))
        if kind == "extra_forbidden" and loc:
            loc[-1] = "?"  # the body's own key
        shown.append(f"{_printable('.'.join(loc), 100)}: {_printable(kind, 60)}")
    return "; ".join(shown)


async def _refused(request: Request, problem: Exception) -> Response:
    """A route's refusal (4xx), logged; FastAPI's own answer to it."""
    assert isinstance(problem, HTTPException)
    if problem.status_code < 500:
        _log_refusal(request, problem.status_code, str(problem.detail))
    return await http_exception_handler(request, problem)


def _log_refusal(request: Request, status: int, detail: str) -> None:
    """One line, as the access guard's, saying whose token the request carried."""
    who = getattr(request.state, "who", None)
    by = (
        "" if who is None else " (the operator's token)" if who == OPERATOR else f" ({who}'s token)"
    )
    log_refusal(request.method, request.url.path, status, f"{detail}{by}")


async def _database_busy(request: Request, problem: Exception) -> JSONResponse:
    response = error(503, f"the database is busy ({_printable(problem, 100)}); retry shortly")
    response.headers["retry-after"] = "1"
    return response


async def _internal_error(request: Request, problem: Exception) -> JSONResponse:
    return error(500, "internal error: the server's log has the details")


def add_error_handlers(app: FastAPI) -> None:
    app.add_exception_handler(RequestValidationError, _invalid_request)
    app.add_exception_handler(HTTPException, _refused)
    app.add_exception_handler(sqlite3.OperationalError, _database_busy)
    app.add_exception_handler(Exception, _internal_error)
