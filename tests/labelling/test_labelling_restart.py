"""Kill the labelling server at any moment: acknowledged answers survive, and it resumes."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import httpx

from seqrank.labelling.db import LabelDB
from support.pages import start_command

COMMAND = [
    "label",
    "offline",
    "--task",
    "dmc:cartpole_swingup",
    "--scheme",
    "root",
    "--questions",
    "5",
    "--episodes",
    "1",
    "--port",
    "0",
]


def start(directory: Path) -> tuple[subprocess.Popen[str], str]:
    return start_command([*COMMAND, "--out", str(directory)])


def question(url: str) -> dict:
    for _ in range(600):
        state = httpx.get(f"{url}/api/state").json()
        if state["status"] == "question":
            return state["question"]
        time.sleep(0.05)
    raise AssertionError("no question was shown")


def answer(url: str, choice: str) -> dict:
    asked = question(url)
    reply = httpx.post(
        f"{url}/api/answer", json={"question_id": asked["id"], "choice": choice, "latency_ms": 7}
    )
    assert reply.status_code == 200
    return asked


def test_kill_and_restart_loses_nothing_and_resumes(tmp_path):
    directory = tmp_path / "labels"
    process, url = start(directory)
    try:
        first = [answer(url, c) for c in ("left", "right")]
        pending = question(url)  # shown but not answered when the server dies
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait(10)
    assert pending["index"] == 3

    process, url = start(directory)
    try:
        resumed = question(url)
        assert (resumed["id"], resumed["index"]) == (pending["id"], 3)
        assert (resumed["left"], resumed["right"]) == (pending["left"], pending["right"])
        rest = [answer(url, c) for c in ("equal", "left", "timeout")]
        assert process.wait(60) == 0
    finally:
        if process.poll() is None:
            process.kill()
    db = LabelDB.in_dir(directory)
    stored = db.answered_questions()
    assert [q.id for q, _ in stored] == [a["id"] for a in first + rest]
    assert [a.choice for _, a in stored] == ["left", "right", "equal", "left", "timeout"]
    assert [q.index for q, _ in stored] == [0, 1, 2, 3, 4]
    assert (directory / "labels.jsonl").read_text().count('"type": "answer"') == 5
