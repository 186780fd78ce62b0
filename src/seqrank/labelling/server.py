"""The labelling page's HTTP API (FastAPI) and the static page it serves.

Endpoints (all JSON unless said otherwise; errors are `{"detail": "..."}` with a 4xx code):
- `GET /`                      the page (static HTML/JS/CSS, no build step)
- `GET /api/state`             what to show now: a question, training, a survey, or done
- `POST /api/answer`           `{question_id, choice, latency_ms}`; choice is left / right /
                               equal / skip / timeout; committed before the reply
- `GET /api/clips/{id}.mp4`    a segment's clip (rendered on first request, then cached)
- `POST /api/survey`           `{run, satisfaction 1-5, criteria}` after a study method
- `GET /api/labels.jsonl`      every answer so far in the documented JSONL format

With a token set, every request must carry it (`?token=`, the `X-Seqrank-Token` header or
the cookie the page gets on its first visit).
"""

from __future__ import annotations

import secrets
from collections.abc import Awaitable, Callable
from importlib import resources
from typing import Literal

from fastapi import APIRouter, FastAPI, HTTPException, Request, Response
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, PlainTextResponse
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, ConfigDict, Field

from seqrank.labelling.db import AnswerConflict, LabelDB, NotAsked, StoredQuestion
from seqrank.labelling.human import Hub, PageSettings
from seqrank.labelling.jsonl import export_lines

STATIC = resources.files("seqrank.labelling") / "static"
TOKEN_COOKIE = "seqrank_token"


class AnswerIn(BaseModel):
    model_config = ConfigDict(extra="forbid")
    question_id: int = Field(ge=1)
    choice: Literal["left", "right", "equal", "skip", "timeout"]
    latency_ms: float = Field(ge=0, le=24 * 3600 * 1000)


class SurveyIn(BaseModel):
    model_config = ConfigDict(extra="forbid")
    run: str = Field(min_length=1, max_length=200)
    satisfaction: int = Field(ge=1, le=5)
    criteria: str = Field(max_length=5000)


def create_app(hub: Hub) -> FastAPI:
    app = FastAPI(title="seqrank labelling", docs_url=None, redoc_url=None, openapi_url=None)
    app.middleware("http")(_token_check(hub.settings))

    @app.get("/", response_class=HTMLResponse)
    def index() -> str:
        return (STATIC / "index.html").read_text()

    app.mount("/static", StaticFiles(directory=str(STATIC)), name="static")
    app.include_router(_question_routes(hub))
    app.include_router(_clip_routes(hub))
    app.include_router(_survey_routes(hub))
    app.include_router(_export_routes(hub.db))
    return app


def _token_check(
    settings: PageSettings,
) -> Callable[[Request, Callable[[Request], Awaitable[Response]]], Awaitable[Response]]:
    """A middleware that turns away requests without the access token (when one is set)."""

    async def require_token(
        request: Request, call_next: Callable[[Request], Awaitable[Response]]
    ) -> Response:
        token = settings.token
        if token is None:
            return await call_next(request)
        given = (
            request.query_params.get("token")
            or request.headers.get("x-seqrank-token")
            or request.cookies.get(TOKEN_COOKIE)
            or ""
        )
        if not secrets.compare_digest(given.encode(), token.encode()):
            return JSONResponse(
                {"detail": "missing or wrong access token: open the address the server printed"},
                status_code=401,
            )
        response = await call_next(request)
        # the page's own requests (clips, answers) then carry the token without a query
        response.set_cookie(TOKEN_COOKIE, token, httponly=True, samesite="strict")
        return response

    return require_token


def _question_routes(hub: Hub) -> APIRouter:
    router = APIRouter()
    db, settings = hub.db, hub.settings

    @router.get("/api/state")
    def state() -> dict[str, object]:
        common: dict[str, object] = {
            "run": hub.run,
            "scheme": hub.scheme,
            "annotator": settings.annotator,
            "countdown_s": settings.countdown_s,
            "sessions": hub.sessions_total,
            "message": hub.message,
        }
        question = db.pending_question()
        if question is not None:
            return {**common, **_question_state(hub, question)}
        if hub.phase == "survey" and hub.survey_run is not None:
            return {**common, "status": "survey", "survey_run": hub.survey_run}
        status = "done" if hub.phase == "done" else "waiting"
        return {**common, "status": status}

    @router.post("/api/answer")
    def answer(body: AnswerIn) -> dict[str, object]:
        question = db.question(body.question_id)
        if question is None:
            raise HTTPException(404, f"unknown question {body.question_id}")
        try:
            stored, duplicate = db.record_answer(
                question, body.choice, body.latency_ms, settings.annotator
            )
        except (AnswerConflict, NotAsked) as conflict:
            raise HTTPException(409, str(conflict)) from None
        return {
            "accepted": True,
            "duplicate": duplicate,
            "question_id": question.id,
            "answer": stored.answer,
        }

    return router


def _question_state(hub: Hub, question: StoredQuestion) -> dict[str, object]:
    """The `/api/state` fields of a question waiting for its answer."""
    # the scheme and length of the question's own session, which may not be the hub's run
    session = hub.db.session_row(question.run, question.session)
    scheme = session["scheme"] if session is not None else hub.scheme
    questions = session["questions"] if session is not None else 0
    return {
        "status": "question",
        "run": question.run,
        "scheme": scheme,
        "question": {
            "id": question.id,
            "session": question.session + 1,
            "index": question.index + 1,
            "questions": questions,
            "left": _side(question, question.left),
            "right": _side(question, question.right),
        },
    }


def _side(question: StoredQuestion, segment: int) -> dict[str, object]:
    role = None
    if question.defender is not None:
        role = "defender" if segment == question.defender else "challenger"
    return {"segment": segment, "clip": f"/api/clips/{segment}.mp4", "role": role}


def _clip_routes(hub: Hub) -> APIRouter:
    router = APIRouter()

    @router.get("/api/clips/{segment_id}.mp4")
    def clip(segment_id: int) -> FileResponse:
        row = hub.db.segment(segment_id)
        if row is None:
            raise HTTPException(404, f"unknown segment {segment_id}")
        if row["states"] is None:
            raise HTTPException(
                404, f"segment {segment_id} has no saved physics states, so it cannot be shown"
            )
        if hub.renderer is None:
            raise HTTPException(503, "this server renders no clips")
        path = hub.renderer.clip(segment_id)
        return FileResponse(path, media_type="video/mp4")

    return router


def _survey_routes(hub: Hub) -> APIRouter:
    router = APIRouter()

    @router.post("/api/survey")
    def survey(body: SurveyIn) -> dict[str, object]:
        stored = hub.db.survey(body.run)
        # a stored survey is answered again as a duplicate even after its phase has passed
        if stored is None and (hub.phase != "survey" or hub.survey_run != body.run):
            raise HTTPException(409, f"no survey is open for run {body.run!r}")
        scheme = hub.scheme if stored is None else stored["scheme"]
        created = hub.db.record_survey(
            body.run, scheme, body.satisfaction, body.criteria, hub.settings.annotator
        )
        return {"accepted": True, "duplicate": not created}

    return router


def _export_routes(db: LabelDB) -> APIRouter:
    router = APIRouter()

    @router.get("/api/labels.jsonl", response_class=PlainTextResponse)
    def labels() -> str:
        return "".join(line + "\n" for line in export_lines(db))

    return router
