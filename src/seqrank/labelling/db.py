"""The labelling database: one SQLite file holding pools, questions, answers and surveys.

Durability is the point: every write is its own transaction, committed (WAL, synchronous
FULL) before the caller hears back, so an answer the page was told about survives a kill at
any moment. Writes made inside `transaction()` join it (as savepoints) and are committed
with it, all or none: an import leaves no half-made session behind.

A question is keyed by (run, session, index); its answer by the question id, so a repeated
submission finds the stored answer instead of writing a second one.

`run` names a training run inside one labelling directory ("online" / "offline", or the
scheme in a study); `session` and `index` count from 0. The schema and the records the
queries return are in `seqrank.labelling.db_records`.
"""

from __future__ import annotations

import contextlib
import json
import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from seqrank.episodes import Segments
from seqrank.labelling.crowd_keys import GOLD_RUN
from seqrank.labelling.db_records import (
    CHOICES,
    PENDING_QUESTION_SQL,
    AnswerConflict,
    NotAsked,
    StoredAnswer,
    StoredQuestion,
    answer_from_row,
    choice_to_answer,
    connect,
    from_blob,
    question_from_row,
    segment_values,
    segments_from_rows,
    to_blob,
)

__all__ = [
    "CHOICES",
    "DB_NAME",
    "AnswerConflict",
    "LabelDB",
    "NotAsked",
    "StoredAnswer",
    "StoredQuestion",
    "choice_to_answer",
    "from_blob",
    "to_blob",
]

DB_NAME = "labels.sqlite"


class LabelDB:
    """Thread-safe access to one labelling database (one connection, one lock)."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.RLock()
        self.changed = threading.Condition(self._lock)
        self._conn = connect(self.path)

    @classmethod
    def in_dir(cls, directory: Path) -> LabelDB:
        return cls(Path(directory) / DB_NAME)

    def close(self) -> None:
        with self._lock:
            self._conn.close()

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        with self._lock:  # (held throughout: an open transaction is this thread's alone)
            if self._conn.in_transaction:  # inside another: a savepoint, committed with it
                yield from _savepoint(self._conn)
                return
            self._conn.execute("BEGIN IMMEDIATE")
            try:
                yield self._conn
            except BaseException:
                if self._conn.in_transaction:  # (SQLite may have rolled back already)
                    self._conn.execute("ROLLBACK")
                raise
            self._conn.execute("COMMIT")
            self.changed.notify_all()

    def _rows(self, sql: str, *params: Any) -> list[sqlite3.Row]:
        with self._lock:
            return list(self._conn.execute(sql, params))

    # for the tables of other modules (`seqrank.labelling.crowd_db`), on this lock, and to
    # make several writes one (`seqrank.labelling.jsonl.import_file`)
    def transaction(self) -> contextlib.AbstractContextManager[sqlite3.Connection]:
        return self._transaction()

    def rows(self, sql: str, *params: Any) -> list[sqlite3.Row]:
        return self._rows(sql, *params)

    def add_tables(self, schema: str) -> None:
        with self._lock:
            self._conn.executescript(schema)

    # ---- meta --------------------------------------------------------------------
    def get_meta(self, key: str) -> str | None:
        rows = self._rows("SELECT value FROM meta WHERE key = ?", key)
        return rows[0]["value"] if rows else None

    def set_meta(self, key: str, value: str) -> None:
        with self._transaction() as conn:
            conn.execute("INSERT OR REPLACE INTO meta VALUES (?, ?)", (key, value))

    # ---- sessions and their pools ------------------------------------------------
    def session_row(self, run: str, session: int) -> sqlite3.Row | None:
        rows = self._rows("SELECT * FROM sessions WHERE run = ? AND session = ?", run, session)
        return rows[0] if rows else None

    def create_session(
        self,
        run: str,
        session: int,
        scheme: str,
        questions: int,
        seed: int,
        defender_side: str,
        segments: Segments,
        pool_ids: list[int] | None = None,
        model_returns: tuple[float, ...] | None = None,
    ) -> None:
        """Store a session and its whole candidate pool, in one transaction.

        `pool_ids` names the segments (default 0, 1, ...): an import keeps a file's names.
        `model_returns`: the reward model's opinion of each pooled segment (`augment
        checked`), kept so that a resumed session asks what it asked before.
        """
        with self._transaction() as conn:
            conn.execute(
                "INSERT INTO sessions VALUES (?, ?, ?, ?, ?, ?, ?)",
                (run, session, scheme, questions, seed, defender_side, time.time()),
            )
            if model_returns is not None:
                conn.execute(
                    "INSERT OR REPLACE INTO meta VALUES (?, ?)",
                    (_opinions_key(run, session), json.dumps(list(model_returns))),
                )
            _insert_segments(conn, run, session, segments, pool_ids)

    def store_segments(self, run: str, session: int, segments: Segments) -> None:
        """Store segments outside any session's pool (pool ids 0, 1, ...; kept if stored)."""
        with self._transaction() as conn:
            _insert_segments(conn, run, session, segments, None)

    def model_returns(self, run: str, session: int) -> tuple[float, ...] | None:
        """The model's opinions stored with a session; None when it had none."""
        stored = self.get_meta(_opinions_key(run, session))
        return None if stored is None else tuple(float(v) for v in json.loads(stored))

    def pool(self, run: str, session: int) -> Segments:
        rows = self._rows(
            "SELECT * FROM segments WHERE run = ? AND session = ? ORDER BY pool_id", run, session
        )
        return segments_from_rows(rows)

    def segment_ids(self, run: str, session: int) -> dict[int, int]:
        """pool id -> segment id."""
        rows = self._rows(
            "SELECT id, pool_id FROM segments WHERE run = ? AND session = ?", run, session
        )
        return {r["pool_id"]: r["id"] for r in rows}

    def segment(self, segment_id: int) -> sqlite3.Row | None:
        rows = self._rows("SELECT * FROM segments WHERE id = ?", segment_id)
        return rows[0] if rows else None

    def segments_by_id(self, ids: list[int]) -> dict[int, sqlite3.Row]:
        marks = ",".join("?" * len(ids))
        return {
            r["id"]: r for r in self._rows(f"SELECT * FROM segments WHERE id IN ({marks})", *ids)
        }

    def choices(self, run: str, session: int) -> dict[int, int]:
        """The session's stored choices: key -> position."""
        rows = self._rows(
            "SELECT k, position FROM choices WHERE run = ? AND session = ?", run, session
        )
        return {int(r["k"]): int(r["position"]) for r in rows}

    def add_choice(self, run: str, session: int, k: int, position: int) -> None:
        with self._transaction() as conn:
            conn.execute(
                "INSERT OR IGNORE INTO choices VALUES (?, ?, ?, ?)", (run, session, k, position)
            )

    # ---- questions and answers ---------------------------------------------------
    def ensure_question(
        self,
        run: str,
        session: int,
        index: int,
        first: int,
        second: int,
        defender: int | None,
        left: int,
        right: int,
    ) -> StoredQuestion:
        """The stored question (run, session, index), created if new.

        A stored question must ask about the same two segments: replaying a session after a
        restart that asks something else means the pool or the choices changed.
        """
        with self._transaction() as conn:
            conn.execute(
                "INSERT OR IGNORE INTO questions (run, session, idx, first, second, defender, "
                "left_seg, right_seg, created) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (run, session, index, first, second, defender, left, right, time.time()),
            )
            row = conn.execute(
                "SELECT * FROM questions WHERE run = ? AND session = ? AND idx = ?",
                (run, session, index),
            ).fetchone()
        question = question_from_row(row)
        if (question.first, question.second) != (first, second):
            raise RuntimeError(
                f"{self.path}: run {run!r} session {session} question {index} was stored as "
                f"segments {question.first} vs {question.second}, but the replayed session "
                f"asks {first} vs {second}; the stored session cannot be continued"
            )
        return question

    def question_at(self, run: str, session: int, index: int) -> StoredQuestion | None:
        """The question stored under (run, session, index), if any."""
        rows = self._rows(
            "SELECT * FROM questions WHERE run = ? AND session = ? AND idx = ?", run, session, index
        )
        return question_from_row(rows[0]) if rows else None

    def question(self, question_id: int) -> StoredQuestion | None:
        rows = self._rows("SELECT * FROM questions WHERE id = ?", question_id)
        return question_from_row(rows[0]) if rows else None

    def pending_question(self) -> StoredQuestion | None:
        """The oldest question without an answer (there is at most one while asking)."""
        rows = self._rows(PENDING_QUESTION_SQL)
        return question_from_row(rows[0]) if rows else None

    def answer(self, question_id: int) -> StoredAnswer | None:
        rows = self._rows("SELECT * FROM answers WHERE question_id = ?", question_id)
        return answer_from_row(rows[0]) if rows else None

    def record_answer(
        self,
        question: StoredQuestion,
        choice: str,
        latency_ms: float,
        annotator: str,
        must_be_asked: bool = True,
    ) -> tuple[StoredAnswer, bool]:
        """Commit an answer; returns it and whether it was already stored (a duplicate).

        Raises AnswerConflict when the question already holds a different answer, and
        NotAsked when it has none and is not the question being asked (unless an import
        says `must_be_asked=False`).
        """
        if choice not in CHOICES:
            raise ValueError(f"unknown choice {choice!r}; accepted: {', '.join(CHOICES)}")
        answer = choice_to_answer(choice, question)
        with self._transaction() as conn:
            row = conn.execute(
                "SELECT * FROM answers WHERE question_id = ?", (question.id,)
            ).fetchone()
            if row is not None:
                stored = answer_from_row(row)
                if stored.choice != choice:
                    raise AnswerConflict(
                        f"question {question.id} was already answered {stored.choice!r}; "
                        f"the new answer {choice!r} was not stored"
                    )
                return stored, True
            # checked in the same transaction as the insert: a concurrent duplicate that lost
            # the race must find the stored answer above, not a newer pending question
            pending = conn.execute(PENDING_QUESTION_SQL).fetchone()
            if must_be_asked and (pending is None or pending["id"] != question.id):
                now_asked = "none" if pending is None else str(pending["id"])
                raise NotAsked(
                    f"question {question.id} is not the one being asked (now: {now_asked}); "
                    "reload the page"
                )
            now = time.time()
            conn.execute(
                "INSERT INTO answers VALUES (?, ?, ?, ?, ?, ?)",
                (question.id, choice, answer, latency_ms, annotator, now),
            )
        return StoredAnswer(question.id, choice, answer, latency_ms, annotator, now), False

    def wait_answer(self, question_id: int, stop: threading.Event) -> StoredAnswer | None:
        """Block until the question is answered (None if `stop` is set first)."""
        with self.changed:
            while not stop.is_set():
                stored = self.answer(question_id)
                if stored is not None:
                    return stored
                # answers may also come from another process: look again now and then
                self.changed.wait(0.5)
        return None

    def answered_questions(
        self, run: str | None = None
    ) -> list[tuple[StoredQuestion, StoredAnswer]]:
        # (gold questions train nothing: `seqrank.labelling.gold`)
        where = f"WHERE q.run != '{GOLD_RUN}'" if run is None else "WHERE q.run = ?"
        rows = self._rows(
            "SELECT q.*, a.choice, a.answer, a.latency_ms, a.annotator, a.answered_at "
            f"FROM questions q JOIN answers a ON a.question_id = q.id {where} ORDER BY q.id",
            *(() if run is None else (run,)),
        )
        return [(question_from_row(r), answer_from_row(r, r["id"])) for r in rows]

    def count(self, run: str, session: int) -> int:
        """The session's questions answered: a team's other opinions on them (stored under
        negative indices) are not among them, so a session is complete when this reaches
        its number of questions, however many opinions were given."""
        rows = self._rows(
            "SELECT COUNT(*) AS n FROM questions q JOIN answers a ON a.question_id = q.id "
            "WHERE q.run = ? AND q.session = ? AND q.idx >= 0",
            run,
            session,
        )
        return int(rows[0]["n"])

    def sessions(self) -> list[sqlite3.Row]:
        return self._rows("SELECT * FROM sessions ORDER BY created, run, session")

    # ---- surveys -----------------------------------------------------------------
    def survey(self, run: str) -> sqlite3.Row | None:
        rows = self._rows("SELECT * FROM surveys WHERE run = ?", run)
        return rows[0] if rows else None

    def surveys(self) -> list[sqlite3.Row]:
        return self._rows("SELECT * FROM surveys ORDER BY answered_at")

    def record_survey(
        self, run: str, scheme: str, satisfaction: int, criteria: str, annotator: str
    ) -> bool:
        """Store a survey; False if one was already stored for `run` (kept as it was)."""
        with self._transaction() as conn:
            cursor = conn.execute(
                "INSERT OR IGNORE INTO surveys VALUES (?, ?, ?, ?, ?, ?)",
                (run, scheme, satisfaction, criteria, annotator, time.time()),
            )
            return cursor.rowcount == 1


def _insert_segments(
    conn: sqlite3.Connection, run: str, session: int, segments: Segments, ids: list[int] | None
) -> None:
    for row, pool_id in enumerate(ids if ids is not None else range(len(segments.features))):
        conn.execute(
            "INSERT OR IGNORE INTO segments (run, session, pool_id, features, rewards, "
            "states, context) VALUES (?, ?, ?, ?, ?, ?, ?)",
            segment_values(run, session, pool_id, segments, row),
        )


def _savepoint(conn: sqlite3.Connection) -> Iterator[sqlite3.Connection]:
    """A write inside an open transaction: undone alone if it fails, else kept for the
    enclosing transaction to commit or roll back."""
    conn.execute("SAVEPOINT inner")
    try:
        yield conn
    except BaseException:
        if conn.in_transaction:
            conn.execute("ROLLBACK TO inner")
            conn.execute("RELEASE inner")
        raise
    conn.execute("RELEASE inner")


def _opinions_key(run: str, session: int) -> str:
    return f"model_returns/{run}/{session}"
