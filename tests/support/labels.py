"""Label files as a labelling session records them, written in milliseconds (no page, no
clips): for the tests of `--teacher replay:FILE`."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from seqrank.feedback.label_file import FORMAT, VERSION

TASK = "dmc:cartpole_swingup"  # 5 observations, 1 action
FEATURES = 6


def write_labels(
    path: Path,
    scheme: str = "sequential",
    sessions: Sequence[int] = (4, 4),
    segment_length: int = 20,
    task: str | None = TASK,
    features: int = FEATURES,
    schemes: Sequence[str] = (),
) -> Path:
    """A label file of `sessions` (questions in each) of `scheme` (or `schemes`, one per
    session): the defender, the session's first segment, wins every question. `task`
    None: a header that names no task (files written before headers did)."""
    rng = np.random.default_rng(0)
    header = {"type": "header", "format": FORMAT, "version": VERSION}
    if task is not None:
        header["task"] = task
    lines = [header]
    for session, questions in enumerate(sessions):
        names = [f"run/{session}/{k}" for k in range(questions + 1)]
        lines += [_segment(name, session, segment_length, features, rng) for name in names]
        used = schemes[session] if schemes else scheme
        lines += [_answer(used, session, k, names[0], names[k + 1]) for k in range(questions)]
    path.write_text("\n".join(json.dumps(line) for line in lines) + "\n")
    return path


def _segment(
    name: str, session: int, steps: int, features: int, rng: np.random.Generator
) -> dict[str, object]:
    return {
        "type": "segment",
        "id": name,
        "run": "run",
        "session": session,
        "features": rng.normal(size=(steps, features)).round(3).tolist(),
        "rewards": rng.uniform(size=steps).round(3).tolist(),
        "states": None,
        "context": None,
    }


def _answer(scheme: str, session: int, index: int, first: str, second: str) -> dict[str, object]:
    return {
        "type": "answer",
        "run": "run",
        "scheme": scheme,
        "session": session,
        "index": index,
        "first": first,
        "second": second,
        "defender": first,
        "challenger": second,
        "left": first,
        "right": second,
        "answer": "first",
        "timed_out": False,
        "latency_ms": 10.0,
        "annotator": "tester",
        "answered_at": None,
    }
