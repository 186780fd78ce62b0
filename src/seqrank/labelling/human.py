"""A person as the teacher: sessions whose questions wait for answers from the page.

The scheme runs unchanged; its `ask` stores the question and blocks until the page's answer
is committed. Everything a session depends on is stored before it is used: the candidate
pool, a session seed (which drives uniform draws and the side the defender is shown on) and
every choice of the chooser. After a crash or a kill the same session is therefore replayed
from the database: stored answers are given back at once and the first unanswered question
is asked again, so nothing acknowledged is lost or asked twice.
"""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from seqrank.episodes import Segments
from seqrank.feedback.checking import Recheck
from seqrank.feedback.schemes import SessionRecord, get_scheme, scheme_has_defender
from seqrank.feedback.session import SessionRequest
from seqrank.labelling.clips import ClipRenderer
from seqrank.labelling.crowd_settings import CrowdSettings
from seqrank.labelling.db import LabelDB
from seqrank.types import Answer


class Stopped(Exception):
    """The labelling server is shutting down while a question waits for its answer."""


@dataclass
class PageSettings:
    countdown_s: float = 3.0  # 0: no time limit
    annotator: str = "anonymous"
    token: str | None = None  # required on every request when set
    # "side-by-side": both clips loop together; "one-after-another": each plays in turn (the
    # paper's study instructions)
    playback: str = "side-by-side"


@dataclass
class Hub:
    """What the driver (training or offline labelling) tells the page besides questions."""

    db: LabelDB
    settings: PageSettings
    renderer: ClipRenderer | None = None
    stop: threading.Event = field(default_factory=threading.Event)
    phase: str = "starting"  # starting | asking | training | survey | done
    message: str = "preparing the first questions"
    run: str = ""
    scheme: str = ""
    sessions_total: int = 0
    survey_run: str | None = None
    upcoming: list[int] = field(default_factory=list)  # the session's segments, to prefetch
    clip_source: str = "state"  # clips re-rendered from saved states, or recorded "frames"
    crowd: CrowdSettings | None = None  # a team of annotators (`--annotators`)
    curve: list[tuple[int, float]] = field(default_factory=list)  # (step, eval return)

    def set_phase(self, phase: str, message: str) -> None:
        self.phase, self.message = phase, message


def _session_seed(run_seed: int, run: str, session: int) -> int:
    words = [run_seed, session, *run.encode()]
    return int(np.random.SeedSequence(words).generate_state(1)[0])


class HumanSource:
    """Feedback from the page. `run` names the training run inside the database."""

    def __init__(self, hub: Hub, run: str, seed: int):
        self.hub, self.run, self.seed = hub, run, seed

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        row = stored_session(self.hub.db, self.run, self.seed, request)
        db = self.hub.db
        pool = db.pool(self.run, request.session)
        page_session = _PageSession(
            hub=self.hub,
            run=self.run,
            request=request,
            segment_ids=db.segment_ids(self.run, request.session),
            seed=int(row["seed"]),
            defender_side=str(row["defender_side"]),
            has_defender=scheme_has_defender(request.scheme),
            same_pool=np.array_equal(pool.features, request.segments.features),
            stored_choices=db.stored_choices(self.run, request.session),
        )
        self.hub.run, self.hub.scheme = self.run, request.scheme
        self.hub.upcoming = sorted(page_session.segment_ids.values())
        if self.hub.renderer is not None:  # render the pool ahead of the questions
            self.hub.renderer.ahead(self.hub.upcoming)
        scheme = get_scheme(request.scheme)
        record = scheme(
            len(pool.features),
            int(row["questions"]),
            page_session.ask,
            np.random.default_rng(page_session.seed),
            page_session.choose,
            _stored_recheck(request, db.model_returns(self.run, request.session)),
        )
        return pool, record


def stored_session(db: LabelDB, run: str, run_seed: int, request: SessionRequest) -> sqlite3.Row:
    """The session's stored row, storing the session and its pool first if it is new."""
    session = request.session
    row = db.session_row(run, session)
    if row is None:
        seed = _session_seed(run_seed, run, session)
        side = "left" if np.random.default_rng(seed).random() < 0.5 else "right"
        opinions = None if request.recheck is None else request.recheck.model_returns
        if opinions is None:  # (a crowd's: its reliability estimate uses them)
            opinions = request.model_returns
        db.create_session(
            run, session, request.scheme, request.questions, seed, side, request.segments,
            model_returns=opinions,
        )  # fmt: skip
        row = db.session_row(run, session)
        assert row is not None
    if row["scheme"] != request.scheme:
        raise RuntimeError(
            f"run {run!r} session {session} was stored with scheme {row['scheme']!r}, "
            f"not {request.scheme!r}"
        )
    return row


@dataclass
class _PageSession:
    """One session's `choose` and `ask` for its scheme, replaying what is stored first.

    Stored choices are given back in order and only new ones are stored, so a session
    replayed after a restart draws the same segments and reaches the same questions.
    """

    hub: Hub
    run: str
    request: SessionRequest
    segment_ids: dict[int, int]  # pool id -> segment id
    seed: int
    defender_side: str  # where a defender is shown, all session long
    has_defender: bool
    same_pool: bool
    stored_choices: list[int]
    choices_made: int = 0
    questions_asked: int = 0

    def choose(
        self, defender: int | None, available: Sequence[int], rng: np.random.Generator
    ) -> int:
        made = self.choices_made
        if made < len(self.stored_choices):
            position = self.stored_choices[made]
        else:
            if self.same_pool:
                position = self.request.chooser(defender, available, rng)
            else:  # the stored pool is not the sampled one (a resumed GPU run): draw uniformly
                position = int(rng.integers(len(available)))
            self.hub.db.add_choice(self.run, self.request.session, made, position)
        self.choices_made += 1
        return position

    def ask(self, first: int, second: int) -> Answer:
        hub, session, index = self.hub, self.request.session, self.questions_asked
        a, b = self.segment_ids[first], self.segment_ids[second]
        if self.has_defender:  # the defender keeps its side so that the person can follow it
            left, right = (a, b) if self.defender_side == "left" else (b, a)
        else:
            swap = np.random.default_rng([self.seed, index]).random() < 0.5
            left, right = (b, a) if swap else (a, b)
        question = hub.db.ensure_question(
            self.run, session, index, a, b, a if self.has_defender else None, left, right
        )
        self.questions_asked += 1
        if hub.renderer is not None:
            hub.renderer.ahead([left, right])
        hub.set_phase("asking", f"session {session + 1}: question {index + 1}")
        stored = hub.db.wait_answer(question.id, hub.stop)
        if stored is None:
            raise Stopped("the labelling server stopped")
        return Answer(stored.answer)


def _stored_recheck(request: SessionRequest, opinions: tuple[float, ...] | None) -> Recheck | None:
    """The re-check the session was first asked with: the model's opinions stored with it
    (they index the stored pool, which a resumed run may not sample again)."""
    if request.recheck is None:
        return None
    return replace(request.recheck, model_returns=opinions)
