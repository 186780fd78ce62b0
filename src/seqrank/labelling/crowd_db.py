"""The crowd's tables in the labelling database: annotators, chains, and who is asked what.

A crowd session's questions are the `questions` table's rows as for one person; beside
them, `crowd_questions` says whom each is assigned to, which chain it belongs to (a second
opinion's chain is `SECOND_OPINIONS`) and whether it was withdrawn (handed over to somebody
else), and `crowd_chains` keeps each chain's share of the session (its questions, its slice
of the pool, its owner, the chain it continues). A question's index in its session is its
key's (`crowd_keys`), so a session replayed after a kill finds every stored row again.
Every change is one transaction of `LabelDB`, committed before the caller hears back, as
everything else there.
"""

from __future__ import annotations

import json
import sqlite3
import time
from collections.abc import Callable
from dataclasses import dataclass

from seqrank.labelling.crowd_keys import GOLD_CHECKS, GOLD_RUN, ChainStep, key_of
from seqrank.labelling.db import (
    AnswerConflict,
    LabelDB,
    NotAsked,
    StoredAnswer,
    StoredQuestion,
    choice_to_answer,
)
from seqrank.labelling.db_records import answer_from_row, question_from_row

SCHEMA = """
CREATE TABLE IF NOT EXISTS crowd_annotators (
    name TEXT PRIMARY KEY, token TEXT NOT NULL, position INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS crowd_chains (
    run TEXT NOT NULL, session INTEGER NOT NULL, chain INTEGER NOT NULL, parent INTEGER,
    budget INTEGER NOT NULL, pool TEXT NOT NULL, owner TEXT, done_at REAL,
    PRIMARY KEY (run, session, chain));
CREATE TABLE IF NOT EXISTS crowd_questions (
    question_id INTEGER PRIMARY KEY REFERENCES questions (id), run TEXT NOT NULL,
    session INTEGER NOT NULL, chain INTEGER NOT NULL, annotator TEXT, assigned_at REAL,
    excluded TEXT, withdrawn_at REAL);
"""
ANSWERS = (  # every answered crowd question, with its chain and its answer
    "SELECT q.id, q.run, q.session, q.idx, q.first, q.second, c.chain, a.choice, a.answer, "
    "a.annotator, a.latency_ms, a.answered_at FROM crowd_questions c "
    "JOIN questions q ON q.id = c.question_id JOIN answers a ON a.question_id = q.id "
    "ORDER BY a.answered_at"
)
UNANSWERED = (
    "SELECT q.*, c.chain, c.annotator, c.assigned_at, c.excluded FROM crowd_questions c "
    "JOIN questions q ON q.id = c.question_id LEFT JOIN answers a ON a.question_id = q.id "
    "WHERE a.question_id IS NULL AND c.withdrawn_at IS NULL"
)

# whether the claimant is not among those a question excludes (comma-separated names)
NOT_EXCLUDED = "instr(',' || c.excluded || ',', ',' || ? || ',') = 0"
# whether the claimant holds (or held) a question on the same pair of the session: nobody
# gives two of the opinions on one pair
HOLDS_PAIR = (
    "SELECT 1 FROM crowd_questions c2 JOIN questions q2 ON q2.id = c2.question_id "
    "WHERE q2.run = q.run AND q2.session = q.session AND q2.first = q.first "
    "AND q2.second = q.second AND c2.annotator = ?"
)
# each pair of a run's sessions that two or more people answered strictly (the evidence a
# reliability estimate counts), with whether `annotator` is one of them
SHARED_PAIRS = (
    "SELECT SUM(a.annotator = ?) > 0 AS theirs FROM answers a "
    "JOIN crowd_questions c ON c.question_id = a.question_id "
    "JOIN questions q ON q.id = a.question_id WHERE q.run = ? "
    "AND a.answer IN ('first', 'second') "
    "GROUP BY q.session, q.first, q.second HAVING COUNT(DISTINCT a.annotator) > 1"
)


class NotYours(Exception):
    """The question is another annotator's to answer."""


@dataclass(frozen=True)
class ChainRow:
    run: str
    session: int
    chain: int
    parent: int | None
    budget: int
    pool: tuple[int, ...]  # pool ids
    owner: str | None


@dataclass(frozen=True)
class Assignment:
    question: StoredQuestion
    chain: int  # SECOND_OPINIONS: a second opinion
    annotator: str | None
    assigned_at: float | None
    withdrawn: bool


class CrowdTables:
    """The crowd's reads and writes, on one `LabelDB` (its lock and transactions)."""

    def __init__(self, db: LabelDB):
        self.db = db
        db.add_tables(SCHEMA)

    # ---- annotators --------------------------------------------------------------
    def annotators(self) -> dict[str, str]:
        """name -> token, in the order they were first given."""
        rows = self.db.rows("SELECT name, token FROM crowd_annotators ORDER BY position")
        return {r["name"]: r["token"] for r in rows}

    def add_annotators(self, tokens: dict[str, str]) -> None:
        """Store new annotators with their tokens; a stored one keeps its token."""
        with self.db.transaction() as conn:
            known = conn.execute("SELECT COUNT(*) FROM crowd_annotators").fetchone()[0]
            for offset, (name, token) in enumerate(tokens.items()):
                conn.execute(
                    "INSERT OR IGNORE INTO crowd_annotators VALUES (?, ?, ?)",
                    (name, token, known + offset),
                )

    # ---- chains ------------------------------------------------------------------
    def chains(self, run: str, session: int) -> list[ChainRow]:
        rows = self.db.rows(
            "SELECT * FROM crowd_chains WHERE run = ? AND session = ? ORDER BY chain", run, session
        )
        return [_chain_from_row(r) for r in rows]

    def add_chain(self, chain: ChainRow) -> ChainRow:
        """Store a chain (kept as it was if stored already); returns the stored one."""
        with self.db.transaction() as conn:
            conn.execute(
                "INSERT OR IGNORE INTO crowd_chains VALUES (?, ?, ?, ?, ?, ?, ?, NULL)",
                (chain.run, chain.session, chain.chain, chain.parent, chain.budget,
                 json.dumps(list(chain.pool)), chain.owner),
            )  # fmt: skip
            row = conn.execute(
                "SELECT * FROM crowd_chains WHERE run = ? AND session = ? AND chain = ?",
                (chain.run, chain.session, chain.chain),
            ).fetchone()
        return _chain_from_row(row)

    def continue_chain(
        self, cut: ChainRow, make: Callable[[list[ChainRow]], ChainRow | None]
    ) -> ChainRow | None:
        """The chain that continues `cut`: the stored one, else `make(stored chains)` stored,
        in one transaction (chains cut at once are numbered in turn)."""
        with self.db.transaction() as conn:
            rows = conn.execute(
                "SELECT * FROM crowd_chains WHERE run = ? AND session = ? ORDER BY chain",
                (cut.run, cut.session),
            ).fetchall()
            stored = [_chain_from_row(r) for r in rows]
            for chain in stored:
                if chain.parent == cut.chain:
                    return chain
            made = make(stored)
            if made is not None:
                conn.execute(
                    "INSERT INTO crowd_chains VALUES (?, ?, ?, ?, ?, ?, ?, NULL)",
                    (made.run, made.session, made.chain, made.parent, made.budget,
                     json.dumps(list(made.pool)), made.owner),
                )  # fmt: skip
            return made

    def finish_chain(self, run: str, session: int, chain: int) -> None:
        """The chain asks nothing more (done, or handed over): its owner is free."""
        with self.db.transaction() as conn:
            conn.execute(
                "UPDATE crowd_chains SET done_at = ? WHERE run = ? AND session = ? AND chain = ? "
                "AND done_at IS NULL",
                (time.time(), run, session, chain),
            )

    def chain_owner(self, run: str, session: int, chain: int) -> str | None:
        rows = self.db.rows(
            "SELECT owner FROM crowd_chains WHERE run = ? AND session = ? AND chain = ?",
            run, session, chain,
        )  # fmt: skip
        return rows[0]["owner"] if rows else None

    # ---- questions ---------------------------------------------------------------
    def pose(
        self, question: StoredQuestion, chain: int, annotator: str | None, excluded: str | None
    ) -> Assignment:
        """Put a stored question to `annotator` (None: whoever claims it first); a question
        posed already keeps its assignment."""
        with self.db.transaction() as conn:
            conn.execute(
                "INSERT OR IGNORE INTO crowd_questions VALUES (?, ?, ?, ?, ?, ?, ?, NULL)",
                (question.id, question.run, question.session, chain, annotator,
                 None if annotator is None else time.time(), excluded),
            )  # fmt: skip
        found = self.assignment(question.id)
        assert found is not None
        return found

    def shared_answers(self, run: str, annotator: str) -> int:
        """How many of `annotator`'s answers in `run` somebody else answered too (the
        evidence their reliability rests on; it never decreases)."""
        sql = f"SELECT COUNT(*) AS n FROM ({SHARED_PAIRS}) WHERE theirs"
        rows = self.db.rows(sql, annotator, run)
        return int(rows[0]["n"])

    def assignment(self, question_id: int) -> Assignment | None:
        rows = self.db.rows("SELECT * FROM crowd_questions WHERE question_id = ?", question_id)
        if not rows:
            return None
        question = self.db.question(question_id)
        assert question is not None
        r = rows[0]
        return Assignment(
            question, r["chain"], r["annotator"], r["assigned_at"], r["withdrawn_at"] is not None
        )

    def claim(self, annotator: str) -> StoredQuestion | None:
        """The question `annotator` should answer now: their own oldest unanswered one;
        else the oldest nobody holds of a chain (the chain becomes theirs), unless a chain
        of theirs is still asking (its next question is coming); else the oldest second
        opinion they may give; None when there is nothing for them."""
        with self.db.transaction() as conn:
            own = conn.execute(
                f"{UNANSWERED} AND c.annotator = ? ORDER BY q.id LIMIT 1", (annotator,)
            ).fetchone()
            if own is not None:
                return question_from_row(own)
            busy = conn.execute(
                "SELECT 1 FROM crowd_chains WHERE owner = ? AND done_at IS NULL", (annotator,)
            ).fetchone()
            chains_too = "" if busy is not None else " OR c.chain >= 0"
            free = conn.execute(
                f"{UNANSWERED} AND c.annotator IS NULL AND ((c.chain < 0 AND {NOT_EXCLUDED} "
                f"AND NOT EXISTS ({HOLDS_PAIR})){chains_too}) ORDER BY c.chain < 0, q.id LIMIT 1",
                (annotator, annotator),
            ).fetchone()
            if free is None:
                return None
            conn.execute(
                "UPDATE crowd_questions SET annotator = ?, assigned_at = ? WHERE question_id = ?",
                (annotator, time.time(), free["id"]),
            )
            if free["chain"] >= 0:
                conn.execute(
                    "UPDATE crowd_chains SET owner = ? WHERE run = ? AND session = ? AND chain = ?",
                    (annotator, free["run"], free["session"], free["chain"]),
                )
            return question_from_row(free)

    def record_answer(
        self, question: StoredQuestion, choice: str, latency_ms: float, annotator: str
    ) -> tuple[StoredAnswer, bool]:
        """Commit `annotator`'s answer; returns it and whether it was stored already.

        Raises AnswerConflict for a different stored answer, NotYours for another's
        question and NotAsked for one handed over: checked in the same transaction as the
        write, so a hand-over and an answer never both happen."""
        answer = choice_to_answer(choice, question)
        with self.db.transaction() as conn:
            row = conn.execute(
                "SELECT * FROM answers WHERE question_id = ?", (question.id,)
            ).fetchone()
            if row is not None:
                stored = answer_from_row(row)
                if stored.choice != choice or stored.annotator != annotator:
                    raise AnswerConflict(
                        f"question {question.id} was already answered; the new answer was "
                        "not stored"
                    )
                return stored, True
            crowd = conn.execute(
                "SELECT annotator, withdrawn_at FROM crowd_questions WHERE question_id = ?",
                (question.id,),
            ).fetchone()
            if crowd is None or crowd["annotator"] != annotator:
                raise NotYours(
                    f"question {question.id} is another annotator's: each answers their own"
                )
            if crowd["withdrawn_at"] is not None:
                raise NotAsked(
                    f"question {question.id} was handed to another annotator after a long "
                    "wait; the page moves on to your next question"
                )
            now = time.time()
            conn.execute(
                "INSERT INTO answers VALUES (?, ?, ?, ?, ?, ?)",
                (question.id, choice, answer, latency_ms, annotator, now),
            )
        return StoredAnswer(question.id, choice, answer, latency_ms, annotator, now), False

    def progress(self, question: StoredQuestion) -> tuple[int, int]:
        """(number, of): the question's place in its chain (1-based) and the chain's
        questions; a second opinion is (1, 1)."""
        key = key_of(question.index)
        if not isinstance(key, ChainStep) or question.run == GOLD_RUN:
            return 1, 1
        rows = self.db.rows(
            "SELECT budget FROM crowd_chains WHERE run = ? AND session = ? AND chain = ?",
            question.run, question.session, key.chain,
        )  # fmt: skip
        return key.k + 1, int(rows[0]["budget"]) if rows else key.k + 1

    def restart_clocks(self) -> int:
        """The server starts: every question held and not answered starts its wait for
        `reassign_after` again now, so time the server was down never counts toward a
        hand-over. Returns how many were waiting."""
        now = time.time()
        with self.db.transaction() as conn:
            restarted = conn.execute(
                "UPDATE crowd_questions SET assigned_at = ? WHERE assigned_at < ? AND "
                "withdrawn_at IS NULL AND question_id NOT IN (SELECT question_id FROM answers)",
                (now, now),
            )
            return restarted.rowcount

    def withdraw_if_unanswered(self, question_id: int) -> bool:
        """Hand a question back (its chain is cut): True unless it was answered first."""
        with self.db.transaction() as conn:
            answered = conn.execute(
                "SELECT 1 FROM answers WHERE question_id = ?", (question_id,)
            ).fetchone()
            if answered is not None:
                return False
            conn.execute(
                "UPDATE crowd_questions SET withdrawn_at = ? WHERE question_id = ? "
                "AND withdrawn_at IS NULL",
                (time.time(), question_id),
            )
            return True

    def withdrawn(self, question_id: int) -> bool:
        found = self.assignment(question_id)
        return found is not None and found.withdrawn

    def unanswered(self, run: str, session: int) -> list[Assignment]:
        """The session's questions put to the team and not answered nor withdrawn, with
        the gold questions given after its answers."""
        rows = self.db.rows(
            f"{UNANSWERED} AND ((q.run = ? AND q.session = ?) OR (q.run = ? AND q.idx IN "
            "(SELECT id FROM questions WHERE run = ? AND session = ?))) ORDER BY q.id",
            run, session, GOLD_RUN, run, session,
        )  # fmt: skip
        return [a for a in (self.assignment(r["id"]) for r in rows) if a is not None]

    def answered_by(self) -> list[tuple[StoredQuestion, str, int, str, float]]:
        """Every answered crowd question: (question, annotator, chain, answer, latency)."""
        rows = self.db.rows(
            "SELECT q.*, c.chain, a.annotator AS who, a.answer, a.latency_ms "
            "FROM crowd_questions c JOIN questions q ON q.id = c.question_id "
            "JOIN answers a ON a.question_id = q.id ORDER BY a.answered_at"
        )
        return [
            (question_from_row(r), r["who"], r["chain"], r["answer"], r["latency_ms"]) for r in rows
        ]

    def gold_given(self, annotator: str) -> int:
        """How many gold questions `annotator` was given (`seqrank.labelling.gold`)."""
        rows = self.db.rows(
            "SELECT COUNT(*) AS n FROM crowd_questions WHERE chain = ? AND annotator = ?",
            GOLD_CHECKS, annotator,
        )  # fmt: skip
        return int(rows[0]["n"])

    def gold_answers(self, run: str, session: int) -> list[tuple[StoredQuestion, str, str, float]]:
        """The answered gold questions given after answers of the session: (question,
        annotator, answer, latency); a gold question's index is its occasion's id."""
        rows = self.db.rows(
            "SELECT g.*, a.annotator AS who, a.answer, a.latency_ms FROM questions g "
            "JOIN answers a ON a.question_id = g.id JOIN questions t ON t.id = g.idx "
            "WHERE g.run = ? AND t.run = ? AND t.session = ? ORDER BY g.id",
            GOLD_RUN, run, session,
        )  # fmt: skip
        return [(question_from_row(r), r["who"], r["answer"], r["latency_ms"]) for r in rows]

    def answer_rows(self) -> list[sqlite3.Row]:
        """Every answered crowd question: its pair, chain, choice, author and times."""
        return self.db.rows(ANSWERS)

    def withdrawn_count(self) -> dict[str, int]:
        """Questions handed over, by the annotator they were taken from."""
        rows = self.db.rows(
            "SELECT annotator, COUNT(*) AS n FROM crowd_questions WHERE withdrawn_at IS NOT "
            "NULL AND annotator IS NOT NULL GROUP BY annotator"
        )
        return {r["annotator"]: int(r["n"]) for r in rows}


def _chain_from_row(row: sqlite3.Row) -> ChainRow:
    return ChainRow(
        row["run"],
        row["session"],
        row["chain"],
        row["parent"],
        row["budget"],
        tuple(json.loads(row["pool"])),
        row["owner"],
    )
