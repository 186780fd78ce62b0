"""What the page shows besides questions: a small state machine behind one lock.

The driver (training, offline labelling, a study) moves the page from phase to phase; the
server reads a consistent `PageView` of it. Every change is one call under the lock, so a
reader never sees half of a paired change (a survey's phase without its run, a session's
run without its scheme). The moves allowed:

    starting -> waiting | asking | training | survey | done
    waiting, asking, training -> waiting | asking | training | survey | done
    survey -> waiting            (its answer closes it; nothing else leaves it)
    done -> done                 (final: a new message only)

A survey is opened with its run (`open_survey`) and never by `move`: `survey_run` is set
exactly while the phase is survey.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, replace
from enum import StrEnum
from typing import Any


class Phase(StrEnum):
    STARTING = "starting"  # the page is open, nothing asked yet
    WAITING = "waiting"  # episodes or clips are being prepared, or a survey was answered
    ASKING = "asking"  # a session's questions are out
    TRAINING = "training"  # between sessions
    SURVEY = "survey"  # a study method's survey is open
    DONE = "done"  # nothing more will be asked


_ANY = frozenset({Phase.WAITING, Phase.ASKING, Phase.TRAINING, Phase.SURVEY, Phase.DONE})
MOVES: dict[Phase, frozenset[Phase]] = {
    Phase.STARTING: _ANY,
    Phase.WAITING: _ANY,
    Phase.ASKING: _ANY,
    Phase.TRAINING: _ANY,
    Phase.SURVEY: frozenset({Phase.WAITING}),
    Phase.DONE: frozenset({Phase.DONE}),
}


class PhaseError(RuntimeError):
    """A move the page's state machine does not allow."""


@dataclass(frozen=True)
class PageView:
    """The page's state at one moment."""

    phase: Phase = Phase.STARTING
    message: str = "preparing the first questions"
    run: str = ""
    scheme: str = ""
    survey_run: str | None = None  # set exactly while the phase is survey
    sessions_total: int = 0
    upcoming: tuple[int, ...] = ()  # the session's segments, for the page to prefetch
    curve: tuple[tuple[int, float], ...] = ()  # (step, eval return)


class PageState:
    """The page's one `PageView`, changed only by the moves above, under one lock.

    Lock order: this lock, then the database's (`show_training` may read the database
    while holding it); nothing takes this lock while holding the database's."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._view = PageView()

    def now(self) -> PageView:
        with self._lock:
            return self._view

    def move(self, phase: Phase, message: str) -> None:
        """Go to `phase` with `message` (a survey opens with `open_survey` only); a phase
        is named by `Phase` alone, so a misspelt one is caught where it is written."""
        if not isinstance(phase, Phase):
            raise TypeError(f"a page phase is a Phase, not {phase!r}")
        if phase is Phase.SURVEY:
            raise PhaseError("a survey opens with its run: open_survey(run, scheme, message)")
        with self._lock:
            self._go(phase, message=message)

    def show_session(self, run: str, scheme: str, upcoming: list[int]) -> None:
        """The session being asked: its run, scheme and segments (the phase stays)."""
        with self._lock:
            self._view = replace(self._view, run=run, scheme=scheme, upcoming=tuple(upcoming))

    def open_survey(self, run: str, scheme: str, message: str) -> None:
        with self._lock:
            self._go(Phase.SURVEY, message=message, survey_run=run, scheme=scheme)

    def close_survey(self) -> None:
        """The survey is answered: the page waits for what comes next."""
        with self._lock:
            self._go(Phase.WAITING)

    def show_training(self, message: str, still_asking: Callable[[], bool]) -> None:
        """Training goes on: say so, unless a session is asking and `still_asking()`."""
        with self._lock:
            if self._view.phase is Phase.ASKING and still_asking():
                return
            self._go(Phase.TRAINING, message=message)

    def plan(self, sessions: int) -> None:
        """The number of sessions the page will ask."""
        with self._lock:
            self._view = replace(self._view, sessions_total=sessions)

    def add_eval(self, step: int, value: float) -> None:
        with self._lock:
            self._view = replace(self._view, curve=(*self._view.curve, (step, value)))

    def _go(self, phase: Phase, **changes: Any) -> None:
        current = self._view.phase
        if phase not in MOVES[current]:
            raise PhaseError(f"the page cannot go from {current} to {phase}")
        if phase is not Phase.SURVEY:
            changes["survey_run"] = None
        self._view = replace(self._view, phase=phase, **changes)
