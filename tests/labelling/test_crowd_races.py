"""A team's session under races (issue 48, item 3): a question handed over while its
first annotator's answer arrives late counts once, and a session killed (SIGKILL) in the
middle of a hand-over replays to the state it had, and finishes."""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from seqrank.episodes import Segments
from seqrank.labelling.crowd_db import CrowdTables
from seqrank.labelling.db import LabelDB, NotAsked
from support.crowd import bare_team, team_request
from support.pages import page_client

TESTS = Path(__file__).resolve().parents[1]


def test_a_late_answer_and_the_hand_over_of_its_question_never_both_happen(tmp_path):
    db = LabelDB.in_dir(tmp_path)
    tables = CrowdTables(db)
    pool = Segments(np.zeros((2, 3, 4), np.float32), np.zeros((2, 3)), [None] * 2, [None] * 2)
    db.create_session("offline", 0, "pairwise", 1, 0, "left", pool)
    a, b = sorted(db.segment_ids("offline", 0).values())
    for k in range(60):
        question = db.ensure_question("offline", 0, k, a, b, None, a, b)
        tables.pose(question, 0, "alice", None)
        start, result = threading.Barrier(2), {}

        def hand_over(question=question, start=start, result=result) -> None:
            start.wait()
            result["withdrawn"] = tables.withdraw_if_unanswered(question.id)

        def answer(question=question, start=start, result=result) -> None:
            start.wait()
            try:
                tables.record_answer(question, "left", 900.0, "alice")
                result["answered"] = True
            except NotAsked:
                result["answered"] = False

        threads = [threading.Thread(target=hand_over), threading.Thread(target=answer)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert result["withdrawn"] != result["answered"], (k, result)  # one of the two, once
        stored = db.answer(question.id) is not None
        assert (stored, tables.withdrawn(question.id)) == (result["answered"], result["withdrawn"])
    db.close()


class LateMember(threading.Thread):
    """Answers what the page shows `name`, every other answer about the hand-over deadline
    or well after it; records (question id, status) of each post."""

    def __init__(self, client: TestClient, name: str, patience: float, done: threading.Event):
        super().__init__(daemon=True)
        self.client, self.name_, self.patience, self.done = client, name, patience, done
        self.rng, self.posts = random.Random(name), []

    def run(self) -> None:
        while not self.done.is_set():
            state = self.client.get("/api/state").json()
            if state["status"] != "question":
                time.sleep(0.01)
                continue
            # every other answer is late: around the deadline (the race), and one in four
            # long after it, so that a hand-over happens however loaded the machine is
            late = len(self.posts) % 2 == 1
            long_late = len(self.posts) % 4 == 1
            factor = 5.0 if long_late else self.rng.uniform(0.9, 1.6) if late else 0.1
            time.sleep(self.patience * factor)
            body = {"question_id": state["question"]["id"], "choice": "left", "latency_ms": 5}
            reply = self.client.post("/api/answer", json=body)
            self.posts.append((state["question"]["id"], reply.status_code))


def test_a_question_handed_over_while_its_late_answer_arrives_counts_once(tmp_path):
    patience = 0.3
    hub = bare_team(tmp_path / "labels", ["alice", "bob"], patience)
    done, found = threading.Event(), {}
    members = []
    for name in ("alice", "bob"):
        client = page_client(hub)
        client.headers["X-Seqrank-Token"] = hub.crowd.tokens[name]
        members.append(LateMember(client, name, patience, done))

    def drive() -> None:
        request = team_request("sequential", 10, 2, spare=3)
        found["pool"], found["record"] = hub.source("offline", 0).ask_session(request)
        done.set()

    driver = threading.Thread(target=drive, daemon=True)
    driver.start()
    for member in members:
        member.start()
    assert done.wait(120), "the session did not finish"
    for member in members:
        member.join(10)
    tables, record = hub.crowd.tables, found["record"]
    pool_of = {s: p for p, s in hub.db.segment_ids("offline", 0).items()}
    stored = {q.id: (q, who, answer) for q, who, chain, answer, _ in tables.answered_by()}
    counted = sorted(
        (pool_of[q.first], pool_of[q.second], answer, who) for q, who, answer in stored.values()
    )
    # every stored answer counts once, and nothing else does
    assert counted == sorted(
        (a.first, a.second, a.answer.value, who)
        for a, who in zip(record.answers, record.crowd.answered_by, strict=True)
    )
    withdrawn = "SELECT question_id FROM crowd_questions WHERE withdrawn_at IS NOT NULL"
    handed_over = {row["question_id"] for row in hub.db.rows(withdrawn)}
    assert handed_over, "no question was handed over: the race was not run"
    for member in members:
        for question_id, status in member.posts:
            if status == 200:  # acknowledged: stored, as its author's, and not handed over
                assert stored[question_id][1] == member.name_
                assert question_id not in handed_over
            else:  # refused: handed over first, and never stored
                assert status == 409 and question_id in handed_over
                assert question_id not in stored
    hub.stop.set()
    hub.db.close()


def child(directory: Path, step: str) -> subprocess.CompletedProcess[str]:
    """The session's process (`support/handover_child.py`), run to its end or its kill."""
    env = {**os.environ, "PYTHONPATH": str(TESTS), "OMP_NUM_THREADS": "1"}
    command = [sys.executable, "-m", "support.handover_child", str(directory), step]
    return subprocess.run(command, capture_output=True, text=True, env=env, timeout=300)


def snapshot(directory: Path) -> dict[str, set[tuple]]:
    """What a replay must find again: questions, answers, choices, chains, assignments."""
    db = LabelDB.in_dir(directory)
    tables = {
        "questions": "SELECT id, idx, first, second, defender, left_seg, right_seg FROM questions",
        "answers": "SELECT question_id, choice, answer, annotator FROM answers",
        "choices": "SELECT k, position FROM choices",
        "chains": "SELECT chain, parent, budget, pool FROM crowd_chains",
        "owners": "SELECT chain, owner FROM crowd_chains WHERE owner IS NOT NULL",
        "assigned": "SELECT question_id, chain, annotator, excluded, withdrawn_at IS NOT NULL "
        "FROM crowd_questions WHERE annotator IS NOT NULL",
    }
    found = {name: {tuple(row) for row in db.rows(sql)} for name, sql in tables.items()}
    db.close()
    return found


@pytest.mark.parametrize("step", ["withdrawn", "continued"])
def test_a_team_killed_in_the_middle_of_a_hand_over_replays_to_the_same_state(tmp_path, step):
    directory = tmp_path / "labels"
    killed = child(directory, step)
    assert killed.returncode == -signal.SIGKILL, killed.stderr[-2000:]
    before = snapshot(directory)
    handed = [row for row in before["assigned"] if row[4]]
    assert len(handed) == 1 and handed[0][2] == "alice"  # killed in alice's hand-over
    cut = handed[0][1]

    finished = child(directory, "none")
    assert finished.returncode == 0, finished.stderr[-2000:]
    after = snapshot(directory)
    for name, rows in before.items():  # all of it found again, none of it changed
        assert rows <= after[name], name
    continuations = [row for row in after["chains"] if row[1] == cut]
    assert len(continuations) == 1  # one hand-over, not one a start
    answers = json.loads(finished.stdout)
    assert len(answers) == len(after["answers"]) == 8  # the budget, each answer once
    assert sum(who == "alice" for *_, who in answers) == 1

    replayed = child(directory, "replay")  # nobody answers: all of it comes back
    assert replayed.returncode == 0, replayed.stderr[-2000:]
    assert json.loads(replayed.stdout) == answers
    assert snapshot(directory) == after
