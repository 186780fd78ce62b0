"""A labelling page driven in-process, and `seqrank` started as a process."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

from fastapi.testclient import TestClient

from seqrank.labelling.app import OfflineOptions, ServerOptions, open_hub, run_offline
from seqrank.labelling.server import create_app

TASK = "dmc:cartpole_swingup"


class Page:
    """An offline labelling session of `questions` questions served to a TestClient."""

    def __init__(
        self,
        directory: Path,
        scheme: str,
        questions: int,
        token: str | None = None,
        task: str = TASK,
        segment_length: int = 50,
    ):
        self.directory = directory
        options = ServerOptions(token=token, countdown_s=3.0, annotator="tester")
        self.hub = open_hub(directory, task, options)
        self.client = TestClient(create_app(self.hub))
        if token:
            self.client.headers["X-Seqrank-Token"] = token
        offline = OfflineOptions(task, scheme, questions, 1, segment_length, 1, 0, None)
        self.done = threading.Event()
        self.error: list[BaseException] = []

        def drive() -> None:
            try:
                run_offline(directory, offline, self.hub, lambda text: None)
            except BaseException as error:  # reported by the test
                self.error.append(error)
            finally:
                self.done.set()

        self.thread = threading.Thread(target=drive, daemon=True)
        self.thread.start()

    def state(self) -> dict:
        for _ in range(600):
            state = self.client.get("/api/state").json()
            if state["status"] != "waiting" or self.done.is_set():
                return state
            self.done.wait(0.05)
        raise AssertionError("the page never showed a question")

    def question(self) -> dict:
        state = self.state()
        assert state["status"] == "question", state
        return state["question"]

    def answer(self, choice: str, latency: float = 500.0):
        question = self.question()
        body = {"question_id": question["id"], "choice": choice, "latency_ms": latency}
        return question, self.client.post("/api/answer", json=body)

    def close(self) -> None:
        self.hub.stop.set()
        self.thread.join(10)
        self.hub.renderer.close()
        self.hub.db.close()


def start_command(args: list[str]) -> tuple[subprocess.Popen[str], str]:
    """Start `seqrank ARGS`; returns the process and the page address it printed."""
    process = subprocess.Popen(
        [sys.executable, "-m", "seqrank", *args],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert process.stderr is not None
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        line = process.stderr.readline()
        found = re.search(r"labelling page: (http://\S+)", line)
        if found:  # keep reading what it prints, so that it never blocks on a full pipe
            threading.Thread(target=process.stderr.read, daemon=True).start()
            return process, found.group(1).rstrip("/")
        if not line and process.poll() is not None:
            break
    process.kill()
    raise AssertionError("the server did not print its address")
