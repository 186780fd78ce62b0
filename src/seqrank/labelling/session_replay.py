"""A session at the page as its database holds it: the one replay path, for one person
and for a team.

Everything a session depends on is stored before it is used: its candidate pool, its seed,
the model's opinions of the pool and every choice of its chooser. A session asked again
(after a kill, or in a resumed run) is asked from what is stored: the stored pool and
opinions, the stored choices given back in turn. Where the pool the run samples now is not
the stored one (a resumed run on a GPU), the run's chooser, which ranks the pool it
sampled, gives way to a uniform draw over the stored one.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace

import numpy as np

from seqrank.episodes import Segments
from seqrank.feedback.schemes import Chooser, uniform_choice
from seqrank.feedback.session import SessionRequest
from seqrank.labelling.db import LabelDB
from seqrank.labelling.streams import one_person_draws, session_seed


@dataclass(frozen=True)
class StoredSession:
    run: str
    session: int
    seed: int  # the session's seed (`streams.session_seed`), stored with it
    questions: int
    defender_side: str  # where one person is shown a defender, all session long
    pool: Segments
    segment_ids: dict[int, int]  # pool id -> segment id
    request: SessionRequest  # the request as stored: its pool and the model's opinions
    choices: ReplayedChoices


class ReplayedChoices:
    """The session's chooser: stored choices given back by key, new ones stored first."""

    def __init__(self, db: LabelDB, run: str, session: int, chooser: Chooser):
        self.db, self.run, self.session, self.base = db, run, session, chooser
        self.stored = db.choices(run, session)  # key -> position

    def chooser(self, keys: Iterator[int]) -> Chooser:
        """A chooser whose n-th choice is stored under the n-th of `keys`."""

        def choose(defender: int | None, available: Sequence[int], rng: np.random.Generator) -> int:
            key = next(keys)
            if key in self.stored:
                return self.stored[key]
            position = self.base(defender, available, rng)
            self.db.add_choice(self.run, self.session, key, position)
            return position

        return choose


def open_session(db: LabelDB, run: str, run_seed: int, request: SessionRequest) -> StoredSession:
    """The session of `request` as stored, storing it and its pool first if it is new."""
    row = _session_row(db, run, run_seed, request)
    session = request.session
    pool = db.pool(run, session)
    opinions = db.model_returns(run, session)
    same_pool = np.array_equal(pool.features, request.segments.features)
    # a model's scores index the new draw, not the stored pool; collection order's choice
    # reads positions only, and the stored pool was stored in that order
    kept = same_pool or request.in_order
    chooser = request.chooser if kept else uniform_choice
    recheck = request.recheck
    if recheck is not None:  # the opinions index the stored pool
        recheck = replace(recheck, model_returns=opinions)
    stored = replace(request, segments=pool, recheck=recheck, model_returns=opinions)
    return StoredSession(
        run,
        session,
        int(row["seed"]),
        int(row["questions"]),
        str(row["defender_side"]),
        pool,
        db.segment_ids(run, session),
        stored,
        ReplayedChoices(db, run, session, chooser),
    )


def _session_row(db: LabelDB, run: str, run_seed: int, request: SessionRequest) -> sqlite3.Row:
    session = request.session
    row = db.session_row(run, session)
    if row is None:
        seed = session_seed(run_seed, run, session)
        side = "left" if one_person_draws(seed).random() < 0.5 else "right"
        opinions = None if request.recheck is None else request.recheck.model_returns
        if opinions is None:  # (a team's: its reliability estimate uses them)
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
