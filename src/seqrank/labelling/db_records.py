"""What the labelling database stores, and how rows and arrays are encoded.

The schema, the records a query returns (questions, answers, pools) and the conversions
between them and SQLite rows; the queries themselves live in `seqrank.labelling.db`.
"""

from __future__ import annotations

import io
import sqlite3
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from seqrank.episodes import Segments

CHOICES = ("left", "right", "equal", "skip", "timeout")

SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS sessions (
    run TEXT NOT NULL, session INTEGER NOT NULL, scheme TEXT NOT NULL,
    questions INTEGER NOT NULL, seed INTEGER NOT NULL, defender_side TEXT NOT NULL,
    created REAL NOT NULL, PRIMARY KEY (run, session));
CREATE TABLE IF NOT EXISTS segments (
    id INTEGER PRIMARY KEY AUTOINCREMENT, run TEXT NOT NULL, session INTEGER NOT NULL,
    pool_id INTEGER NOT NULL, features BLOB NOT NULL, rewards BLOB NOT NULL, states BLOB,
    context INTEGER, UNIQUE (run, session, pool_id));
CREATE TABLE IF NOT EXISTS choices (
    run TEXT NOT NULL, session INTEGER NOT NULL, k INTEGER NOT NULL, position INTEGER NOT NULL,
    PRIMARY KEY (run, session, k));
CREATE TABLE IF NOT EXISTS questions (
    id INTEGER PRIMARY KEY AUTOINCREMENT, run TEXT NOT NULL, session INTEGER NOT NULL,
    idx INTEGER NOT NULL, first INTEGER NOT NULL, second INTEGER NOT NULL,
    defender INTEGER, left_seg INTEGER NOT NULL, right_seg INTEGER NOT NULL,
    created REAL NOT NULL, UNIQUE (run, session, idx));
CREATE TABLE IF NOT EXISTS answers (
    question_id INTEGER PRIMARY KEY REFERENCES questions (id), choice TEXT NOT NULL,
    answer TEXT NOT NULL, latency_ms REAL NOT NULL, annotator TEXT NOT NULL,
    answered_at REAL NOT NULL);
CREATE TABLE IF NOT EXISTS surveys (
    run TEXT PRIMARY KEY, scheme TEXT NOT NULL, satisfaction INTEGER NOT NULL,
    criteria TEXT NOT NULL, annotator TEXT NOT NULL, answered_at REAL NOT NULL);
"""

# the oldest question without an answer: the one the page shows
PENDING_QUESTION_SQL = (
    "SELECT q.* FROM questions q LEFT JOIN answers a ON a.question_id = q.id "
    "WHERE a.question_id IS NULL ORDER BY q.id LIMIT 1"
)


def connect(path: Path) -> sqlite3.Connection:
    """Open (creating if new) a database whose commits survive a kill at any moment."""
    conn = sqlite3.connect(path, check_same_thread=False, isolation_level=None)
    conn.row_factory = sqlite3.Row
    conn.execute("PRAGMA journal_mode=WAL")
    conn.execute("PRAGMA synchronous=FULL")
    conn.execute("PRAGMA busy_timeout=10000")
    conn.executescript(SCHEMA)
    return conn


@dataclass(frozen=True)
class StoredQuestion:
    id: int
    run: str
    session: int
    index: int
    first: int  # segment ids (the segments table)
    second: int
    defender: int | None
    left: int
    right: int


@dataclass(frozen=True)
class StoredAnswer:
    question_id: int
    choice: str  # what was clicked: left / right / equal / skip / timeout
    answer: str  # mapped to the question's order: first / second / equal / skip
    latency_ms: float
    annotator: str
    answered_at: float


class AnswerConflict(Exception):
    """The question already holds a different answer."""


class NotAsked(Exception):
    """The question has no answer and is not the one being asked."""


def to_blob(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, np.asarray(array), allow_pickle=False)
    return buffer.getvalue()


def from_blob(blob: bytes) -> np.ndarray:
    return np.load(io.BytesIO(blob), allow_pickle=False)


def choice_to_answer(choice: str, question: StoredQuestion) -> str:
    """Map what was clicked on screen back to the question's own order."""
    if choice in ("left", "right"):
        shown = question.left if choice == "left" else question.right
        return "first" if shown == question.first else "second"
    return "skip" if choice == "timeout" else choice


def segment_values(
    run: str, session: int, pool_id: int, segments: Segments, row: int
) -> tuple[object, ...]:
    """The `segments` table's columns (after `id`) for row `row` of a pool."""
    states = segments.states[row]
    return (
        run,
        session,
        pool_id,
        to_blob(segments.features[row].astype(np.float32)),
        to_blob(np.asarray(segments.rewards[row], np.float64)),
        None if states is None else to_blob(states),
        segments.contexts[row],
    )


def question_from_row(row: sqlite3.Row) -> StoredQuestion:
    return StoredQuestion(
        row["id"],
        row["run"],
        row["session"],
        row["idx"],
        row["first"],
        row["second"],
        row["defender"],
        row["left_seg"],
        row["right_seg"],
    )


def answer_from_row(row: sqlite3.Row, question_id: int | None = None) -> StoredAnswer:
    """`question_id` overrides the row's, for joins where the question's column is `id`."""
    return StoredAnswer(
        row["question_id"] if question_id is None else question_id,
        row["choice"],
        row["answer"],
        row["latency_ms"],
        row["annotator"],
        row["answered_at"],
    )


def segments_from_rows(rows: list[sqlite3.Row]) -> Segments:
    if not rows:
        raise ValueError("no segments stored")
    return Segments(
        np.stack([from_blob(r["features"]) for r in rows]),
        np.stack([from_blob(r["rewards"]) for r in rows]),
        [None if r["states"] is None else from_blob(r["states"]) for r in rows],
        [r["context"] for r in rows],
    )
