"""A team's labelling page driven in-process: the offline driver in a thread, and one
HTTP client per annotator (or the operator), each with their own token."""

from __future__ import annotations

import os
import random
import re
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

from fastapi.testclient import TestClient

from seqrank.labelling.app import OfflineOptions, ServerOptions, open_hub, run_offline
from seqrank.labelling.crowd_team import open_team
from seqrank.labelling.human import Hub, Stopped
from support.pages import TASK, page_client


class TeamPage:
    """`sessions` offline sessions of `questions` questions for the team `names`."""

    def __init__(
        self,
        directory: Path,
        names: list[str],
        scheme: str = "sequential",
        questions: int = 12,
        sessions: int = 1,
        overlap: float = 0.3,
        reassign_after: float = 60.0,
    ):
        self.hub: Hub = open_hub(directory, TASK, ServerOptions(countdown_s=3.0))
        open_team(self.hub, names, overlap, reassign_after)
        options = OfflineOptions(
            TASK, scheme, questions, sessions, 50, 1, 0, None, "full", tuple(names), overlap
        )
        self.done = threading.Event()
        self.errors: list[BaseException] = []

        def drive() -> None:
            try:
                run_offline(directory, options, self.hub, lambda text: None)
            except Stopped:
                pass
            except BaseException as error:  # reported by the test
                self.errors.append(error)
            finally:
                self.done.set()

        self.thread = threading.Thread(target=drive, daemon=True)
        self.thread.start()

    def client(self, name: str) -> TestClient:
        """The page as `name` sees it ("operator": the operator's token)."""
        crowd = self.hub.crowd
        client = page_client(self.hub)
        token = crowd.operator_token if name == "operator" else crowd.tokens[name]
        client.headers["X-Seqrank-Token"] = token
        return client

    def close(self) -> None:
        self.hub.stop.set()
        self.thread.join(20)
        if self.hub.renderer is not None:
            self.hub.renderer.close()
        self.hub.db.close()


class Annotator(threading.Thread):
    """Answers every question shown to `name`, at `pace` seconds, until the session is
    done or `stop_after` answers; records (question id, choice, status) of each post."""

    def __init__(
        self,
        page: TeamPage,
        name: str,
        pace: float = 0.02,
        stop_after: int = 10**9,
        choose: Callable[[dict], str] | None = None,
    ):
        super().__init__(daemon=True)
        self.page, self.name_, self.pace, self.stop_after = page, name, pace, stop_after
        rng = random.Random(name)
        self.choose = choose or (lambda question: rng.choice(["left", "right"]))
        self.posts: list[tuple[int, str, int]] = []

    def run(self) -> None:
        client = self.page.client(self.name_)
        while not self.page.done.is_set() and len(self.posts) < self.stop_after:
            state = client.get("/api/state").json()
            if state["status"] != "question":
                time.sleep(0.02)
                continue
            question = state["question"]
            time.sleep(self.pace)
            choice = self.choose(question)
            body = {"question_id": question["id"], "choice": choice, "latency_ms": self.pace * 1000}
            reply = client.post("/api/answer", json=body)
            self.posts.append((question["id"], choice, reply.status_code))


def run_team(page: TeamPage, annotators: list[Annotator], timeout: float = 120.0) -> None:
    for annotator in annotators:
        annotator.start()
    assert page.done.wait(timeout), "the team's sessions did not finish"
    for annotator in annotators:
        annotator.join(10)
    assert not page.errors, page.errors


def start_team(args: list[str], names: tuple[str, ...]) -> tuple[subprocess.Popen[str], dict]:
    """Start `seqrank ARGS` for the team `names`; returns the process and the address it
    printed for each name and for the operator."""
    process = subprocess.Popen(
        [sys.executable, "-m", "seqrank", *args],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert process.stderr is not None
    addresses: dict[str, str] = {}
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(addresses) <= len(names):
        line = process.stderr.readline()
        found = re.search(r"(\S+)'s page: (http://\S+)", line)
        if found:
            addresses[found.group(1)] = found.group(2)
        elif not line and process.poll() is not None:
            break
    if len(addresses) <= len(names):
        process.kill()
        raise AssertionError(f"the team's addresses were not printed: {addresses}")
    threading.Thread(target=process.stderr.read, daemon=True).start()  # never a full pipe
    return process, addresses


def bare_team(
    directory: Path,
    names: list[str],
    reassign_after: float,
    overlap: float = 0.0,
    overlap_until: int = 0,
):
    """A team's hub with no clips and no driver: the test asks its sessions itself."""
    from seqrank.labelling.db import LabelDB
    from seqrank.labelling.human import PageSettings

    hub = Hub(LabelDB.in_dir(directory), PageSettings(0.0, "tester", None))
    open_team(hub, names, overlap, reassign_after, overlap_until)
    return hub


def answering(
    hub: Hub, name: str, choose: Callable[..., str], done: threading.Event
) -> threading.Thread:
    """`name` answers whatever the team's tables give them, until `done`, in a thread (join
    it before the database closes)."""
    tables = hub.crowd.tables

    def run() -> None:
        while not done.is_set():
            question = tables.claim(name)
            if question is None:
                time.sleep(0.005)
            else:
                tables.record_answer(question, choose(question), 5.0, name)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def team_request(scheme: str, questions: int, people: int, spare: int = 1):
    """A session over featureless segments, `spare` times the pool its chains need."""
    import numpy as np

    from seqrank.episodes import Segments
    from seqrank.feedback.schemes import segments_needed, uniform_choice
    from seqrank.feedback.session import SessionRequest

    n = spare * segments_needed(scheme, questions, people)
    features = np.arange(n * 12, dtype=np.float32).reshape(n, 3, 4)
    pool = Segments(features, np.zeros((n, 3)), [None] * n, [None] * n)
    rng = np.random.default_rng(0)
    return SessionRequest(scheme, questions, 0, pool, uniform_choice, rng, 0.0, chains=people)
