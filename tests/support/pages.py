"""A labelling page driven in-process, and `seqrank` started as a process."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from fastapi.testclient import TestClient

from seqrank.episodes import Segments
from seqrank.labelling.access import Access
from seqrank.labelling.app import OfflineOptions, ServerOptions, open_hub, run_offline
from seqrank.labelling.db import LabelDB
from seqrank.labelling.human import Hub, PageSettings
from seqrank.labelling.server import create_app

TASK = "dmc:cartpole_swingup"
LOCAL = "http://127.0.0.1:8765"  # a Host the guard serves (TestClient's own is "testserver")
# a labelling run of minutes: ten questions on cartpole, small nets and clips
TINY = [
    "--task", "dmc:cartpole_swingup", "--steps", "1800", "--seed-steps", "300",
    "--unsup-steps", "900", "--feedback-frequency", "500", "--max-feedback", "10",
    "--reward-batch", "5", "--hidden", "32", "--batch", "32", "--reward-hidden", "32",
    "--reward-epochs", "5", "--eval-every", "900", "--eval-episodes", "1",
    "--heldout-pairs", "50", "--device", "cpu", "--countdown", "0", "--port", "0",
    "--size", "64",  # small clips: the page, not the picture, is under test
]  # fmt: skip


def page_client(hub: Hub, access: Access | None = None, **options: Any) -> TestClient:
    """A TestClient of the page's app, addressed as a browser on this machine would."""
    return TestClient(create_app(hub, access), base_url=LOCAL, **options)


def waiting_question_hub(directory: Path, token: str | None = None) -> Hub:
    """A hub whose database holds one pairwise question waiting for its answer: no driver
    thread and no clips (its segments have no physics states), so it costs milliseconds."""
    db = LabelDB.in_dir(directory)
    pool = Segments(np.zeros((2, 3, 4), np.float32), np.zeros((2, 3)), [None, None], [None, None])
    db.create_session("offline", 0, "pairwise", 1, 0, "left", pool)
    first, second = sorted(db.segment_ids("offline", 0).values())
    db.ensure_question("offline", 0, 0, first, second, None, first, second)
    hub = Hub(db, PageSettings(0.0, "tester", token))
    hub.state.show_session("offline", "pairwise", [])
    return hub


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
        augment: str = "full",
        sessions: int = 1,
    ):
        self.directory = directory
        options = ServerOptions(token=token, countdown_s=3.0, annotator="tester")
        self.hub = open_hub(directory, task, options)
        self.client = page_client(self.hub)
        if token:
            self.client.headers["X-Seqrank-Token"] = token
        offline = OfflineOptions(
            task, scheme, questions, sessions, segment_length, 1, 0, None, augment
        )
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


class Participant(threading.Thread):
    """Answers every question 'left' and every survey with the next satisfaction score."""

    def __init__(self, url: str, scores: list[int]):
        super().__init__(daemon=True)
        self.url, self.scores, self.halt = url, list(scores), threading.Event()

    def run(self) -> None:
        while not self.halt.is_set():
            try:
                state = httpx.get(f"{self.url}/api/state").json()
            except httpx.HTTPError:
                return  # the server has gone: the study is over
            if state["status"] == "question":
                body = {"question_id": state["question"]["id"], "choice": "left", "latency_ms": 5}
                httpx.post(f"{self.url}/api/answer", json=body)
            elif state["status"] == "survey":
                body = {
                    "run": state["survey_run"],
                    "satisfaction": self.scores.pop(0),
                    "criteria": "x",
                }
                httpx.post(f"{self.url}/api/survey", json=body)
            else:
                time.sleep(0.05)


def team_question_for_bob(directory: Path) -> Hub:
    """alice and bob at a page whose one question (id 1) is posed to bob."""
    from seqrank.labelling.crowd_team import open_team

    hub = waiting_question_hub(directory)
    open_team(hub, ["alice", "bob"], 0.0, 60.0)
    question = hub.db.question(1)
    assert question is not None
    hub.crowd.tables.pose(question, 0, "bob", None)
    return hub
