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
