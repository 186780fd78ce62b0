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
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.episodes import Segments

FORMAT, VERSION = "seqrank-labels", 1


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
        rows = [self.segments[n] for n in names]  # (states and context are optional)
        states = [None if r.get("states") is None else np.asarray(r["states"]) for r in rows]
        return Segments(
            np.asarray([r["features"] for r in rows], np.float32),
            np.asarray([r["rewards"] for r in rows], np.float64),
            states,
            [r.get("context") for r in rows],
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


def _segment_names(asked: list[Any], run: str) -> tuple[dict[int, int], dict[int, str]]:
    """Each asked segment's session (the first it appears in) and its name in the file:
    run/session/position within the session."""
    session_of: dict[int, int] = {}
    for session, _, first, second, _, _ in asked:
        session_of.setdefault(first, session)
        session_of.setdefault(second, session)
    start: dict[int, int] = {}
    for index, session in session_of.items():
        start[session] = min(start.get(session, index), index)
    return session_of, {i: f"{run}/{s}/{i - start[s]}" for i, s in session_of.items()}


def store_lines(
    store: Any, header: dict[str, Any], run: str, scheme: str, annotator: str
) -> Iterable[str]:
    """A run's label store (`feedback.labels.LabelStore`) in this format: its segments and
    every asked question in order. A run saved before the store kept its questions gives
    its asked pairs, without skips and roles, and per-step rewards spread evenly over each
    segment (their sum, the segment's true return, is exact). `header` holds task,
    obs_dim, act_dim and segment_length."""
    asked = list(store.asked) or [
        (s, scheme, a, b, {1.0: "first", 0.0: "second"}.get(label, "equal"), False)
        for s, a, b, label, inferred in zip(
            store.session, store.first, store.second, store.labels, store.inferred, strict=True
        )
        if not inferred
    ]
    yield json.dumps({"type": "header", "format": FORMAT, "version": VERSION, **header})
    session_of, names = _segment_names(asked, run)
    for index in sorted(names):
        states = store.segment_states[index]
        yield json.dumps(
            {
                "type": "segment",
                "id": names[index],
                "run": run,
                "session": session_of[index],
                "features": np.asarray(store.segments[index]).tolist(),
                "rewards": _rewards(store, index).tolist(),
                "states": None if states is None else np.asarray(states).tolist(),
                "context": store.segment_contexts[index],
            }
        )
    counters: dict[int, int] = {}
    for session, scheme, first, second, answer, defended in asked:
        counters[session] = counters.get(session, -1) + 1
        yield json.dumps(
            {
                "type": "answer",
                "run": run,
                "scheme": scheme,
                "session": session,
                "index": counters[session],
                "first": names[first],
                "second": names[second],
                "defender": names[first] if defended else None,
                "challenger": names[second] if defended else None,
                "left": names[first],
                "right": names[second],
                "answer": answer,
                "timed_out": False,
                "latency_ms": 0.0,
                "annotator": annotator,
                "answered_at": None,
            }
        )


def _rewards(store: Any, index: int) -> np.ndarray:
    kept = getattr(store, "segment_rewards", [])
    if index < len(kept):
        return np.asarray(kept[index], np.float64)
    steps = len(store.segments[index])
    return np.full(steps, store.segment_returns[index] / steps)
