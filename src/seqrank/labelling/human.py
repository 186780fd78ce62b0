"""A person as the teacher: sessions whose questions wait for answers from the page.

The scheme runs unchanged; its `ask` stores the question and blocks until the page's answer
is committed. Everything a session depends on is stored before it is used: the candidate
pool, a session seed (which drives uniform draws and the side the defender is shown on) and
every choice of the chooser. After a crash or a kill the same session is therefore replayed
from the database: stored answers are given back at once and the first unanswered question
is asked again, so nothing acknowledged is lost or asked twice.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from seqrank.episodes import Segments
from seqrank.feedback.schemes import SessionRecord, get_scheme
from seqrank.feedback.session import SessionRequest
from seqrank.labelling.clips import ClipRenderer
from seqrank.labelling.db import LabelDB
from seqrank.types import Answer


class Stopped(Exception):
    """The labelling server is shutting down while a question waits for its answer."""


@dataclass
class PageSettings:
    countdown_s: float = 3.0  # 0: no time limit
    annotator: str = "anonymous"
    token: str | None = None  # required on every request when set


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

    def check_compatible(self, config: Any, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        hub, db, run, session = self.hub, self.hub.db, self.run, request.session
        row = db.session_row(run, session)
        if row is None:
            seed = _session_seed(self.seed, run, session)
            side = "left" if np.random.default_rng(seed).random() < 0.5 else "right"
            db.create_session(
                run, session, request.scheme, request.questions, seed, side, request.segments
            )
            row = db.session_row(run, session)
            assert row is not None
        if row["scheme"] != request.scheme:
            raise RuntimeError(
                f"run {run!r} session {session} was stored with scheme {row['scheme']!r}, "
                f"not {request.scheme!r}"
            )
        pool = db.pool(run, session)
        ids = db.segment_ids(run, session)
        same_pool = np.array_equal(pool.features, request.segments.features)
        stored_choices = db.stored_choices(run, session)
        seed, side = int(row["seed"]), str(row["defender_side"])
        has_defender = request.scheme != "pairwise"
        made = 0

        def choose(defender: int | None, available: Any, rng: np.random.Generator) -> int:
            nonlocal made
            if made < len(stored_choices):
                position = stored_choices[made]
            elif same_pool:
                position = request.chooser(defender, available, rng)
            else:  # the stored pool is not the sampled one (a resumed GPU run): draw uniformly
                position = int(rng.integers(len(available)))
            if made >= len(stored_choices):
                db.add_choice(run, session, made, position)
            made += 1
            return position

        asked = 0
        questions_total = int(row["questions"])
        hub.run, hub.scheme = run, request.scheme

        def ask(first: int, second: int) -> Answer:
            nonlocal asked
            index = asked
            a, b = ids[first], ids[second]
            if has_defender:
                left, right = (a, b) if side == "left" else (b, a)
            else:
                swap = np.random.default_rng([seed, index]).random() < 0.5
                left, right = (b, a) if swap else (a, b)
            question = db.ensure_question(
                run, session, index, a, b, a if has_defender else None, left, right
            )
            asked += 1
            if hub.renderer is not None:
                hub.renderer.ahead([left, right])
            hub.set_phase("asking", f"session {session + 1}: question {index + 1}")
            stored = db.wait_answer(question.id, hub.stop)
            if stored is None:
                raise Stopped("the labelling server stopped")
            return Answer(stored.answer)

        if hub.renderer is not None:  # render the pool ahead of the questions
            hub.renderer.ahead(sorted(ids.values()))
        scheme = get_scheme(request.scheme)
        record = scheme(
            len(pool.features), questions_total, ask, np.random.default_rng(seed), choose
        )
        return pool, record
