"""A person as the teacher: sessions whose questions wait for answers from the page.

The scheme runs unchanged; its `ask` stores the question and blocks until the page's answer
is committed. Everything a session depends on is stored before it is used
(`session_replay`), so after a crash or a kill the same session is replayed from the
database: stored answers are given back at once and the first unanswered question is asked
again, so nothing acknowledged is lost or asked twice.

The page's `Hub` is what the driver and the server share. Who answers at the page, one
person (`Solo`) or a team (`crowd_team.Team`), is its `mode`: chosen once, before the
page serves, and asked by everything that differs between the two.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from itertools import count
from typing import TYPE_CHECKING, Protocol

from seqrank.episodes import Segments
from seqrank.feedback.schemes import SessionRecord, get_scheme, scheme_has_defender
from seqrank.feedback.session import FeedbackSource, SessionRequest
from seqrank.labelling.clips import ClipRenderer
from seqrank.labelling.crowd_settings import CrowdSettings
from seqrank.labelling.db import LabelDB, StoredAnswer, StoredQuestion
from seqrank.labelling.page_state import PageState, Phase
from seqrank.labelling.session_replay import StoredSession, open_session
from seqrank.labelling.streams import one_person_draws, one_person_side
from seqrank.types import Answer

if TYPE_CHECKING:
    from fastapi import APIRouter


class Stopped(Exception):
    """The labelling server is shutting down while a question waits for its answer."""


class NotATeam(Exception):
    """A team's part was asked of one person's page."""


@dataclass
class PageSettings:
    countdown_s: float = 3.0  # 0: no time limit
    annotator: str = "anonymous"
    token: str | None = None  # required on every request when set
    # "side-by-side": both clips loop together; "one-after-another": each plays in turn (the
    # paper's study instructions)
    playback: str = "side-by-side"


class PageMode(Protocol):
    """Who answers at the page, and all that differs with it: one person or a team."""

    def source(self, hub: Hub, run: str, seed: int) -> FeedbackSource:
        """The driver's teacher: its sessions' questions go to the page."""
        ...

    def tokens(self) -> tuple[tuple[str, str], ...]:
        """(annotator, token) of those with a token of their own."""
        ...

    def question_for(self, hub: Hub, who: str | None) -> StoredQuestion | None:
        """The question `who` should answer now."""
        ...

    def record_answer(
        self, hub: Hub, question: StoredQuestion, choice: str, latency_ms: float, who: str | None
    ) -> tuple[StoredAnswer, bool]:
        """Commit `who`'s answer; returns it and whether it was stored already."""
        ...

    def place(self, question: StoredQuestion, questions: int) -> tuple[int, int]:
        """(number, of): where the question stands among those asked of its person."""
        ...

    def routes(self, hub: Hub) -> list[APIRouter]:
        """The mode's own pages."""
        ...

    def may_export(self, who: str | None) -> bool:
        """Whether `who` may read every answer."""
        ...

    def still_asking(self, hub: Hub) -> bool:
        """Whether the session that set the page asking is still asking."""
        ...

    def announce(
        self, *, base: str, url: str, remote_base: str | None, remote_url: str | None
    ) -> list[str]:
        """The lines that tell the operator where the page is."""
        ...

    @property
    def team(self) -> CrowdSettings:
        """The team (NotATeam for one person)."""
        ...


@dataclass
class Hub:
    """What the driver (training or offline labelling) and the server share: the database,
    the clips, the stop signal, the page's state and who answers (`mode`)."""

    db: LabelDB
    settings: PageSettings
    renderer: ClipRenderer | None = None
    stop: threading.Event = field(default_factory=threading.Event)
    clip_source: str = "state"  # clips re-rendered from saved states, or recorded "frames"
    mode: PageMode = field(default_factory=lambda: Solo())
    state: PageState = field(default_factory=PageState)

    def check_mode_open(self) -> None:
        """Refuse, before anything is stored, a choice of who answers that comes too late."""
        if not isinstance(self.mode, Solo) or self.state.now().phase is not Phase.STARTING:
            raise RuntimeError("who answers at the page is chosen once, before it asks")

    def choose_mode(self, mode: PageMode) -> None:
        """Who answers at the page: chosen once, before the page asks anything."""
        self.check_mode_open()
        self.mode = mode

    def source(self, run: str, seed: int) -> FeedbackSource:
        """Who answers at the page as the teacher of `run` (its name in the database)."""
        return self.mode.source(self, run, seed)

    @property
    def crowd(self) -> CrowdSettings:
        """The page's team (NotATeam on one person's page)."""
        return self.mode.team

    # the page's state as the server reads it (moves go through `state`)
    @property
    def phase(self) -> Phase:
        return self.state.now().phase

    @property
    def upcoming(self) -> tuple[int, ...]:
        return self.state.now().upcoming


class Solo:
    """One person at the page: the question shown is the one being asked."""

    def source(self, hub: Hub, run: str, seed: int) -> HumanSource:
        return HumanSource(hub, run, seed)

    def tokens(self) -> tuple[tuple[str, str], ...]:
        return ()

    def question_for(self, hub: Hub, who: str | None) -> StoredQuestion | None:
        return hub.db.pending_question()

    def record_answer(
        self, hub: Hub, question: StoredQuestion, choice: str, latency_ms: float, who: str | None
    ) -> tuple[StoredAnswer, bool]:
        return hub.db.record_answer(question, choice, latency_ms, hub.settings.annotator)

    def place(self, question: StoredQuestion, questions: int) -> tuple[int, int]:
        return question.index + 1, questions

    def routes(self, hub: Hub) -> list[APIRouter]:
        return []

    def may_export(self, who: str | None) -> bool:
        return True

    def still_asking(self, hub: Hub) -> bool:
        return hub.db.pending_question() is not None  # its phase stays until the next move

    def announce(
        self, *, base: str, url: str, remote_base: str | None, remote_url: str | None
    ) -> list[str]:
        lines = [f"labelling page: {url}"]
        return lines if remote_url is None else [*lines, f"from other machines: {remote_url}"]

    @property
    def team(self) -> CrowdSettings:
        raise NotATeam("this page is one person's: it has no team")


class HumanSource:
    """Feedback from the page. `run` names the training run inside the database."""

    def __init__(self, hub: Hub, run: str, seed: int):
        self.hub, self.run, self.seed = hub, run, seed

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        stored = open_session(self.hub.db, self.run, self.seed, request)
        page_session = _PageSession(self.hub, stored, scheme_has_defender(request.scheme))
        upcoming = sorted(stored.segment_ids.values())
        self.hub.state.show_session(self.run, request.scheme, upcoming)
        if self.hub.renderer is not None:  # render the pool ahead of the questions
            self.hub.renderer.ahead(upcoming)
        scheme = get_scheme(request.scheme)
        record = scheme(
            len(stored.pool.features),
            stored.questions,
            page_session.ask,
            one_person_draws(stored.seed),
            stored.choices.chooser(count()),
            stored.request.recheck,
        )
        return stored.pool, record


@dataclass
class _PageSession:
    """One session's `ask` for its scheme: a stored question is found again, not added."""

    hub: Hub
    stored: StoredSession
    has_defender: bool
    questions_asked: int = 0

    def ask(self, first: int, second: int) -> Answer:
        hub, stored, index = self.hub, self.stored, self.questions_asked
        a, b = stored.segment_ids[first], stored.segment_ids[second]
        if self.has_defender:  # the defender keeps its side so that the person can follow it
            left, right = (a, b) if stored.defender_side == "left" else (b, a)
        else:
            swap = one_person_side(stored.seed, index).random() < 0.5
            left, right = (b, a) if swap else (a, b)
        defender = a if self.has_defender else None
        question = hub.db.ensure_question(
            stored.run, stored.session, index, a, b, defender, left, right
        )
        self.questions_asked += 1
        if hub.renderer is not None:
            hub.renderer.ahead([left, right])
        hub.state.move(Phase.ASKING, f"session {stored.session + 1}: question {index + 1}")
        answer = hub.db.wait_answer(question.id, hub.stop)
        if answer is None:
            raise Stopped("the labelling server stopped")
        return Answer(answer.answer)
