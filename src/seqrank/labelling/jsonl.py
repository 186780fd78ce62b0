"""Labels as data: the JSONL format that online, offline and study labelling share.

One JSON object per line, in this order:

1. `{"type": "header", "format": "seqrank-labels", "version": 1, "task": "dmc:walker_walk",
   "obs_dim": 24, "act_dim": 6, "segment_length": 50}`
2. one `segment` line per segment that some question shows:
   `{"type": "segment", "id": "<run>/<session>/<pool id>", "run", "session",
   "features": [[obs..., action...] per step], "rewards": [true per-step reward],
   "states": [[MuJoCo full physics state] per step] or null, "context": task index or null}`
   `states` (and `context`, Meta-World's task) are the provenance that re-renders the clip;
   `features` is what a reward model trains on; `rewards` is the simulator's truth.
3. one `answer` line per answered question, in the order asked:
   `{"type": "answer", "run", "scheme", "session", "index", "first", "second",
   "defender": segment id or null, "challenger": segment id or null, "left", "right",
   "answer": "first" | "second" | "equal" | "skip", "timed_out": bool, "latency_ms",
   "annotator", "answered_at": unix seconds}`
   `answer` is relative to `first`/`second` (the scheme's order: the defender is `first`);
   `left`/`right` record what the page showed where.
4. one `survey` line per study method: `{"type": "survey", "run", "scheme",
   "satisfaction": 1-5, "criteria", "annotator", "answered_at"}`

Inferred (transitive) labels are not stored: they follow from the answers and the scheme.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.buffer import Segments
from seqrank.labelling.db import LabelDB, from_blob

FORMAT, VERSION = "seqrank-labels", 1
META_KEYS = ("task", "obs_dim", "act_dim", "segment_length")


def segment_name(run: str, session: int, pool_id: int) -> str:
    return f"{run}/{session}/{pool_id}"


def export_lines(db: LabelDB) -> Iterator[str]:
    header: dict[str, Any] = {"type": "header", "format": FORMAT, "version": VERSION}
    for key in META_KEYS:
        value = db.get_meta(key)
        header[key] = None if value is None else json.loads(value)
    yield json.dumps(header)
    answered = db.answered_questions()
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
                "states": None if row["states"] is None else from_blob(row["states"]).tolist(),
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


def export_file(db: LabelDB, path: Path) -> int:
    """Write the JSONL file; returns the number of answers written."""
    lines = list(export_lines(db))
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(path.suffix + ".part")
    partial.write_text("".join(line + "\n" for line in lines))
    partial.replace(path)
    return sum('"type": "answer"' in line for line in lines)


@dataclass
class LabelFile:
    """A parsed JSONL label file."""

    header: dict[str, Any]
    segments: dict[str, dict[str, Any]]
    answers: list[dict[str, Any]]
    surveys: list[dict[str, Any]]

    def sessions(self) -> list[tuple[str, int]]:
        """(run, session) in the order their first answer appears."""
        return list(dict.fromkeys((a["run"], a["session"]) for a in self.answers))

    def session_segments(self, names: list[str]) -> Segments:
        rows = [self.segments[n] for n in names]
        states = [None if r["states"] is None else np.asarray(r["states"]) for r in rows]
        return Segments(
            np.asarray([r["features"] for r in rows], np.float32),
            np.asarray([r["rewards"] for r in rows], np.float64),
            states,
            [r["context"] for r in rows],
        )


_REQUIRED = {
    "segment": ("id", "features", "rewards"),
    "answer": ("run", "scheme", "session", "index", "first", "second", "answer"),
    "survey": ("run", "scheme", "satisfaction"),
}
_ANSWERS = ("first", "second", "equal", "skip")


def read_label_file(path: Path | str) -> LabelFile:
    """Parse and check a label file; a ValueError names the file, line and problem."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"label file {path} does not exist")
    with path.open() as handle:
        return parse_lines(handle, str(path))


def parse_lines(lines: Iterable[str], source: str = "<labels>") -> LabelFile:
    header: dict[str, Any] | None = None
    segments: dict[str, dict[str, Any]] = {}
    answers: list[dict[str, Any]] = []
    surveys: list[dict[str, Any]] = []
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        where = f"{source} line {number}"
        try:
            record = json.loads(line)
        except json.JSONDecodeError as error:
            raise ValueError(f"{where}: not JSON ({error.msg})") from None
        kind = record.get("type") if isinstance(record, dict) else None
        if header is None:
            if kind != "header" or record.get("format") != FORMAT:
                raise ValueError(f"{where}: the first line must be a {FORMAT!r} header")
            if record.get("version") != VERSION:
                version = record.get("version")
                raise ValueError(f"{where}: format version {version!r}; this reads {VERSION}")
            header = record
            continue
        if kind not in _REQUIRED:
            raise ValueError(
                f"{where}: unknown record type {kind!r}; accepted: {', '.join(_REQUIRED)}"
            )
        missing = [key for key in _REQUIRED[kind] if key not in record]
        if missing:
            raise ValueError(f"{where}: {kind} record lacks {', '.join(missing)}")
        if kind == "segment":
            segments[record["id"]] = record
        elif kind == "answer":
            if record["answer"] not in _ANSWERS:
                raise ValueError(
                    f"{where}: answer {record['answer']!r}; accepted: {', '.join(_ANSWERS)}"
                )
            for role in ("first", "second"):
                if record[role] not in segments:
                    raise ValueError(
                        f"{where}: {role} segment {record[role]!r} is not defined above"
                    )
            answers.append(record)
        else:
            surveys.append(record)
    if header is None:
        raise ValueError(f"{source}: empty label file (no header)")
    return LabelFile(header, segments, answers, surveys)


def import_file(db: LabelDB, path: Path) -> int:
    """Load a label file into a labelling database; returns the answers added.

    Importing the same file twice adds nothing. A session already in the database must hold
    the same answers, otherwise nothing is imported and a ValueError says where they differ.
    """
    labels = read_label_file(path)
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
        names = list(dict.fromkeys(n for a in answers for n in (a["first"], a["second"])))
        pool = _pool_ids(names, run, session)
        defended = [a for a in answers if a.get("defender")]
        side = (
            "left"
            if not defended or defended[0].get("left") == defended[0]["defender"]
            else "right"
        )
        db.create_session(
            run,
            session,
            answers[0]["scheme"],
            len(answers),
            0,
            side,
            labels.session_segments(names),
        )
        ids = db.segment_ids(run, session)
        for record in answers:
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
            added += 1
    for survey in labels.surveys:
        db.record_survey(
            survey["run"],
            survey["scheme"],
            int(survey["satisfaction"]),
            str(survey.get("criteria", "")),
            str(survey.get("annotator", "imported")),
        )
    return added


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
