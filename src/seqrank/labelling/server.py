"""The labelling page's HTTP API (FastAPI) and the static page it serves.

Endpoints (all JSON unless said otherwise; errors are `{"detail": "..."}` with a 4xx code):
- `GET /`                      the page (static HTML/JS/CSS, no build step)
- `GET /api/state`             what to show now: a question, training, a survey, or done;
                               with a question, `prefetch`: rendered clips to load ahead
- `POST /api/answer`           `{question_id, choice, latency_ms}`; choice is left / right /
                               equal / skip / timeout; committed before the reply, which
                               carries `next`, the state once the next question is posed
- `GET /api/clips/{id}.mp4`    a segment's clip (rendered on first request, then cached)
- `POST /api/survey`           `{run, satisfaction 1-5, criteria}` after a study method
- `GET /api/labels.jsonl`      every answer so far in the documented JSONL format
- `GET /favicon.ico`          204: the page has no icon (browsers ask for one by themselves)

Every request passes the access guard (`access.py`: Host, Origin, token) and the request
rules (`limits.py`: JSON bodies of bounded size, bounded fields, errors that never echo
the input). With a token set, a request carries the `X-Seqrank-Token` header or the cookie
the page gets when it is opened with `?token=`.
"""

from __future__ import annotations

import time
from importlib import resources
from typing import Annotated, Literal

from fastapi import APIRouter, FastAPI, HTTPException, Path, Request
from fastapi.responses import FileResponse, HTMLResponse, PlainTextResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from seqrank.labelling.access import OPERATOR, Access, AccessGuard
from seqrank.labelling.crowd_db import NotYours
from seqrank.labelling.crowd_keys import GOLD_RUN
from seqrank.labelling.db import AnswerConflict, NotAsked, StoredQuestion
from seqrank.labelling.human import Hub
from seqrank.labelling.jsonl import export_lines
from seqrank.labelling.limits import (
    MAX_ID,
    BodyRules,
    RowId,
    add_error_handlers,
    one_line,
    valid_unicode,
)
from seqrank.labelling.page_state import Phase

STATIC = resources.files("seqrank.labelling") / "static"
NEXT_WAIT_S = 0.5  # an answer's reply waits this long at most for the next question
PREFETCH_CLIPS = 8  # rendered clips offered to the page for loading ahead
# strict: no "1" for 1 or true for 1; finite floats only; nothing beyond the fields
STRICT = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


class AnswerIn(BaseModel):
    model_config = STRICT
    question_id: RowId
    choice: Literal["left", "right", "equal", "skip", "timeout"]
    latency_ms: float = Field(ge=0, le=24 * 3600 * 1000)


class SurveyIn(BaseModel):
    model_config = STRICT
    run: Annotated[str, Field(min_length=1, max_length=200), AfterValidator(one_line)]
    satisfaction: int = Field(ge=1, le=5)
    criteria: Annotated[str, Field(max_length=5000), AfterValidator(valid_unicode)]


def create_app(hub: Hub, access: Access | None = None) -> FastAPI:
    """The page and its API behind the guard; `access` defaults to a loopback server."""
    app = FastAPI(title="seqrank labelling", docs_url=None, redoc_url=None, openapi_url=None)
    add_error_handlers(app)
    app.add_middleware(BodyRules)
    # added last, so it runs first: nothing is read from a request the guard turns away
    app.add_middleware(AccessGuard, access=access or _loopback_access(hub))

    @app.get("/", response_class=HTMLResponse)
    def index() -> str:
        return (STATIC / "index.html").read_text()

    @app.get("/favicon.ico")
    def no_icon() -> Response:  # what browsers ask for by themselves: not a refusal to log
        return Response(status_code=204)

    app.mount("/static", StaticFiles(directory=str(STATIC)), name="static")
    app.include_router(_question_routes(hub))
    for router in hub.mode.routes(hub):  # a team's operator page
        app.include_router(router)
    app.include_router(_clip_routes(hub))
    app.include_router(_survey_routes(hub))
    app.include_router(_export_routes(hub))
    return app


def _loopback_access(hub: Hub) -> Access:
    team = hub.mode.tokens()
    return Access.serving("127.0.0.1", 0, hub.settings.token, annotator_tokens=team)


def _question_routes(hub: Hub) -> APIRouter:
    router = APIRouter()
    db = hub.db

    @router.get("/api/state")
    def state(request: Request) -> dict[str, object]:
        return page_state(hub, request.state.who)

    @router.post("/api/answer")
    def answer(body: AnswerIn, request: Request) -> dict[str, object]:
        who = request.state.who
        question = db.question(body.question_id)
        if question is None:
            raise HTTPException(404, f"unknown question {body.question_id}")
        try:
            stored, duplicate = hub.mode.record_answer(
                hub, question, body.choice, body.latency_ms, who
            )
        except (AnswerConflict, NotAsked) as conflict:
            raise HTTPException(409, str(conflict)) from None
        except NotYours as refused:
            raise HTTPException(403, str(refused)) from None
        return {
            "accepted": True,
            "duplicate": duplicate,
            "question_id": question.id,
            "answer": stored.answer,
            "next": _next_state(hub, question.id, who),
        }

    return router


def page_state(hub: Hub, who: str | None = None) -> dict[str, object]:
    """What the page shows now: a question, a survey, waiting or done; on a team's page,
    what the annotator `who` should do now."""
    view = hub.state.now()
    common: dict[str, object] = {
        "run": view.run,
        "scheme": view.scheme,
        "annotator": hub.settings.annotator if who is None else who,
        "countdown_s": hub.settings.countdown_s,
        "sessions": view.sessions_total,
        "message": view.message,
        "clip_source": hub.clip_source,
        "playback": hub.settings.playback,
    }
    question = hub.mode.question_for(hub, who)
    if question is not None:
        return {**common, **_question_state(hub, question), "prefetch": _prefetch(hub, question)}
    if who == OPERATOR:
        return {**common, "status": "waiting", "message": "this is the operator's address: "
                "the team's work is on /operator"}  # fmt: skip
    if view.phase is Phase.SURVEY:
        return {**common, "status": "survey", "survey_run": view.survey_run}
    status = "done" if view.phase is Phase.DONE else "waiting"
    return {**common, "status": status}


def _next_state(hub: Hub, answered: int, who: str | None = None) -> dict[str, object]:
    """The state after an answer, once the next question is posed (it usually is within
    milliseconds): the page shows it without another request. At most NEXT_WAIT_S."""
    deadline = time.monotonic() + NEXT_WAIT_S
    while True:
        pending = hub.mode.question_for(hub, who)
        moved_on = pending is not None and pending.id != answered
        ended = hub.phase in (Phase.SURVEY, Phase.DONE)
        if moved_on or ended or time.monotonic() > deadline:
            return page_state(hub, who)
        time.sleep(0.005)


def _prefetch(hub: Hub, question: StoredQuestion) -> list[str]:
    """Clips of the session's other segments that are rendered already: the page loads
    them while the person decides, so the next question's clips show at once."""
    if hub.renderer is None:
        return []
    shown = {question.left, question.right}
    ready = [s for s in hub.upcoming if s not in shown and hub.renderer.path(s).exists()]
    return [f"/api/clips/{s}.mp4" for s in ready[:PREFETCH_CLIPS]]


def _question_state(hub: Hub, question: StoredQuestion) -> dict[str, object]:
    """The `/api/state` fields of a question waiting for its answer."""
    # the scheme and length of the question's own session, which may not be the hub's run;
    # a gold question shows as the session of the answer it follows (`labelling.gold`)
    run, number = question.run, question.session
    if run == GOLD_RUN:
        occasion = hub.db.question(question.index)
        run, number = (occasion.run, occasion.session) if occasion is not None else (run, 0)
    session = hub.db.session_row(run, number)
    scheme = session["scheme"] if session is not None else hub.state.now().scheme
    index, questions = hub.mode.place(question, session["questions"] if session is not None else 0)
    return {
        "status": "question",
        "run": run,
        "scheme": scheme,
        "question": {
            "id": question.id,
            "session": number + 1,
            "index": index,
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
    def clip(segment_id: Annotated[int, Path(ge=1, le=MAX_ID)]) -> FileResponse:
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
        view = hub.state.now()
        # a stored survey is answered again as a duplicate even after its phase has passed
        if stored is None and view.survey_run != body.run:
            raise HTTPException(409, "no survey is open for that run")  # (never echoed)
        scheme = view.scheme if stored is None else stored["scheme"]
        created = hub.db.record_survey(
            body.run, scheme, body.satisfaction, body.criteria, hub.settings.annotator
        )
        return {"accepted": True, "duplicate": not created}

    return router


def _export_routes(hub: Hub) -> APIRouter:
    router = APIRouter()

    @router.get("/api/labels.jsonl", response_class=PlainTextResponse)
    def labels(request: Request) -> str:
        if not hub.mode.may_export(request.state.who):  # a team's: not its annotators
            raise HTTPException(403, "every answer is the operator's to read")
        return "".join(line + "\n" for line in export_lines(hub.db))

    return router
