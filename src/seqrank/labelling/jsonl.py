"""Labels between the database and the JSONL label file (format: feedback/label_file.py)."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.feedback.label_file import FORMAT, VERSION, LabelFile, read_label_file
from seqrank.labelling.db import (
    AnswerConflict,
    LabelDB,
    StoredAnswer,
    StoredQuestion,
    from_blob,
)

META_KEYS = ("task", "obs_dim", "act_dim", "segment_length")


def segment_name(run: str, session: int, pool_id: int) -> str:
    return f"{run}/{session}/{pool_id}"


def export_lines(db: LabelDB, agreed_by: int | None = None) -> Iterator[str]:
    """The label file's lines: every answer, or with `agreed_by` only the pairs that many
    people or more answered alike (`agreed_pairs`) and their segments."""
    header: dict[str, Any] = {"type": "header", "format": FORMAT, "version": VERSION}
    for key in META_KEYS:
        value = db.get_meta(key)
        header[key] = None if value is None else json.loads(value)
    yield json.dumps(header)
    answered = db.answered_questions()
    if agreed_by is not None:
        answered = agreed_pairs(answered, agreed_by)
    used = sorted({s for q, _ in answered for s in (q.first, q.second)})
    rows = db.segments_by_id(used) if used else {}
    names = {i: segment_name(r["run"], r["session"], r["pool_id"]) for i, r in rows.items()}
    for segment_id in used:
        row = rows[segment_id]
        yield json.dumps(
            {
                "type": "segment",
                "id": names[segment_id],
                "run": row["run"],
                "session": row["session"],
                "features": from_blob(row["features"]).tolist(),
                "rewards": from_blob(row["rewards"]).tolist(),
                "states": _exported_states(row["states"]),
                "context": row["context"],
            }
        )
    schemes = {(s["run"], s["session"]): s["scheme"] for s in db.sessions()}
    for question, answer in answered:
        defender = None if question.defender is None else names[question.defender]
        challenger = None
        if defender is not None:
            other = question.second if question.defender == question.first else question.first
            challenger = names[other]
        yield json.dumps(
            {
                "type": "answer",
                "run": question.run,
                "scheme": schemes.get((question.run, question.session)),
                "session": question.session,
                "index": question.index,
                "first": names[question.first],
                "second": names[question.second],
                "defender": defender,
                "challenger": challenger,
                "left": names[question.left],
                "right": names[question.right],
                "answer": answer.answer,
                "timed_out": answer.choice == "timeout",
                "latency_ms": answer.latency_ms,
                "annotator": answer.annotator,
                "answered_at": answer.answered_at,
            }
        )
    for survey in db.surveys():
        yield json.dumps({"type": "survey", **dict(survey)})


def agreed_pairs(
    answered: list[tuple[StoredQuestion, StoredAnswer]], people: int
) -> list[tuple[StoredQuestion, StoredAnswer]]:
    """One answer for each pair of a session that `people` or more answered, every one of
    them strictly and for the same segment (whichever way round it was shown): the session's
    own question where it is among them, else the first asked. A team's gold pairs
    (`seqrank.labelling.gold`) without the operator answering any."""
    alike: dict[tuple[str, int, int, int], list[tuple[StoredQuestion, StoredAnswer]]] = {}
    for question, answer in answered:
        low, high = sorted((question.first, question.second))
        pair = (question.run, question.session, low, high)
        alike.setdefault(pair, []).append((question, answer))
    kept = []
    for given in alike.values():
        preferred = {_preferred(question, answer) for question, answer in given}
        authors = {answer.annotator for _, answer in given}
        if len(authors) >= people and len(preferred) == 1 and None not in preferred:
            kept.append(min(given, key=lambda qa: (qa[0].index < 0, qa[0].id)))
    return sorted(kept, key=lambda qa: qa[0].id)


def _preferred(question: StoredQuestion, answer: StoredAnswer) -> int | None:
    """The segment a strict answer prefers; None for any other answer."""
    return {"first": question.first, "second": question.second}.get(answer.answer)


def export_file(db: LabelDB, path: Path, agreed_by: int | None = None) -> int:
    """Write the JSONL file; returns the number of answers written."""
    lines = list(export_lines(db, agreed_by))
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(path.suffix + ".part")
    partial.write_text("".join(line + "\n" for line in lines))
    partial.replace(path)
    return sum('"type": "answer"' in line for line in lines)


def import_file(db: LabelDB, path: Path) -> int:
    """Load a label file into a labelling database; returns the answers added.

    One transaction: the whole file or, on any error, nothing (a session half stored would
    look imported, and a second try would add nothing to it). Importing the same file twice
    adds nothing. A session already in the database must hold the same answers, otherwise
    nothing is imported and a ValueError says where they differ; a record that cannot be
    stored is named the same way.
    """
    labels = read_label_file(path)
    with db.transaction():
        _check_meta(db, labels.header, path)
        plan = []
        for run, session in labels.sessions():
            answers = [a for a in labels.answers if (a["run"], a["session"]) == (run, session)]
            if db.session_row(run, session) is not None:
                _check_same(db, run, session, answers, path)
            else:
                plan.append((run, session, answers))
        added = 0
        for run, session, answers in plan:
            where = f"{path}: run {run!r} session {session}"
            added += _failing_as(where, _import_session, db, labels, where, session, answers)
        for survey in labels.surveys:
            _failing_as(f"{path}: survey of run {survey['run']!r}", _import_survey, db, survey)
    return added


class ImportFailed(ValueError):
    """A record of the file could not be stored; the message names it, in one line."""


# what a record the file reader let through can raise once it is being stored
_STORE_ERRORS = (ValueError, TypeError, KeyError, RuntimeError, AnswerConflict, sqlite3.Error)


def _failing_as(where: str, write: Callable[..., int], *args: Any) -> int:
    """`write(*args)`, its failure an ImportFailed that says `where`."""
    try:
        return write(*args)
    except ImportFailed:
        raise
    except _STORE_ERRORS as problem:
        if isinstance(problem, KeyError) and problem.args:
            why = f"no {problem.args[0]!r}"
        else:
            why = " ".join(str(problem).split()) or type(problem).__name__
        raise ImportFailed(f"{where}: {why}; nothing imported") from problem


def _import_session(
    db: LabelDB, labels: LabelFile, where: str, session: int, answers: list[dict[str, Any]]
) -> int:
    """Store one session of the file: its pool, then its questions and answers."""
    run = answers[0]["run"]
    names = list(dict.fromkeys(n for a in answers for n in (a["first"], a["second"])))
    pool = _pool_ids(names, run, session)
    defended = [a for a in answers if a.get("defender")]
    side = "left" if not defended or defended[0].get("left") == defended[0]["defender"] else "right"
    asked = sum(int(a["index"]) >= 0 for a in answers)  # (a team's opinions: below 0)
    segments = labels.session_segments(names)
    pool_ids = [pool[name] for name in names]  # (a file's pool ids may have gaps)
    db.create_session(
        run, session, answers[0]["scheme"], asked or len(answers), 0, side, segments, pool_ids
    )
    ids = db.segment_ids(run, session)
    for record in answers:
        asked_as = f"{where} question {record['index']}"
        _failing_as(asked_as, _import_answer, db, run, session, record, ids, pool)
    return len(answers)


def _import_answer(
    db: LabelDB,
    run: str,
    session: int,
    record: dict[str, Any],
    ids: dict[int, int],
    pool: dict[str, int],
) -> int:
    first, second = ids[pool[record["first"]]], ids[pool[record["second"]]]
    left = ids[pool[record.get("left", record["first"])]]
    right = second if left == first else first
    defender = ids[pool[record["defender"]]] if record.get("defender") else None
    question = db.ensure_question(
        run, session, int(record["index"]), first, second, defender, left, right
    )
    db.record_answer(
        question,
        _choice(record, left, first),
        float(record.get("latency_ms", 0.0)),
        str(record.get("annotator", "imported")),
        must_be_asked=False,
    )
    return 1


def _import_survey(db: LabelDB, survey: dict[str, Any]) -> int:
    db.record_survey(
        survey["run"],
        survey["scheme"],
        int(survey["satisfaction"]),
        str(survey.get("criteria", "")),
        str(survey.get("annotator", "imported")),
    )
    return 0


def _pool_ids(names: list[str], run: str, session: int) -> dict[str, int]:
    """Keep `<run>/<session>/<pool id>` names as they are; number any other names in order."""
    prefix = f"{run}/{session}/"
    kept = {
        n: int(n[len(prefix) :])
        for n in names
        if n.startswith(prefix) and n[len(prefix) :].isdigit()
    }
    if len(kept) == len(names):
        return kept
    return {name: k for k, name in enumerate(names)}


def _choice(record: dict[str, Any], left: int, first: int) -> str:
    answer = record["answer"]
    if record.get("timed_out"):
        return "timeout"
    if answer in ("first", "second"):
        first_on_left = left == first
        return "left" if (answer == "first") == first_on_left else "right"
    return str(answer)


def _check_meta(db: LabelDB, header: dict[str, Any], path: Path) -> None:
    for key in META_KEYS:
        stored, given = db.get_meta(key), header.get(key)
        if stored is None:
            if given is not None:
                db.set_meta(key, json.dumps(given))
        elif given is not None and json.loads(stored) != given:
            raise ValueError(
                f"{path}: {key} is {given!r} but the database holds {json.loads(stored)!r}"
            )


def _check_same(
    db: LabelDB, run: str, session: int, answers: list[dict[str, Any]], path: Path
) -> None:
    stored = {q.index: a.answer for q, a in db.answered_questions(run) if q.session == session}
    for record in answers:
        have = stored.get(int(record["index"]))
        if have is not None and have != record["answer"]:
            raise ValueError(
                f"{path}: run {run!r} session {session} question {record['index']} is "
                f"{record['answer']!r} in the file but {have!r} in the database; nothing imported"
            )


def _exported_states(blob: bytes | None) -> list[Any] | None:
    """Physics states as lists; recorded frames (uint8 images of a task without MuJoCo
    state) are left out: megabytes per segment, and nothing can re-render from them."""
    states = None if blob is None else from_blob(blob)
    return None if states is None or states.dtype == np.uint8 else states.tolist()
