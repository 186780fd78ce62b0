"""`seqrank label online --annotators` as a team runs it: each person answers from their own
address while the agent trains, and the run learns whose answers to trust."""

from __future__ import annotations

import json
import threading
import time

import httpx

from support.crowd import start_team
from support.pages import TINY

TEAM = ("alice", "bob")


class Member(threading.Thread):
    """Answers every question their own page shows them, with their own token."""

    def __init__(self, address: str, choice: str):
        super().__init__(daemon=True)
        base, token = address.split("?token=")
        self.base, self.choice, self.halt = base.rstrip("/"), choice, threading.Event()
        self.headers = {"X-Seqrank-Token": token}
        self.answered = 0

    def run(self) -> None:
        with httpx.Client(headers=self.headers) as client:
            while not self.halt.is_set():
                try:
                    state = client.get(f"{self.base}/api/state").json()
                except httpx.HTTPError:
                    return  # the server has gone: the run is over
                if state["status"] != "question":
                    time.sleep(0.05)
                    continue
                body = {"question_id": state["question"]["id"], "choice": self.choice}
                reply = client.post(f"{self.base}/api/answer", json={**body, "latency_ms": 5})
                self.answered += reply.status_code == 200


def test_a_team_teaches_an_online_run_from_their_own_pages(tmp_path):
    run = tmp_path / "run"
    args = ["label", "online", "--out", str(run), "--annotators", ",".join(TEAM), *TINY]
    process, addresses = start_team([*args, "--overlap", "0.5"], TEAM)
    members = [Member(addresses[name], "left") for name in TEAM]
    for member in members:
        member.start()
    try:
        assert process.wait(900) == 0  # generous: a loaded 2-core machine is slow
    finally:
        for member in members:
            member.halt.set()
    assert "operator" in addresses and "/operator?token=" in addresses["operator"]
    summary = json.loads((run / "summary.json").read_text())
    assert summary["asked"] == 10  # the budget, shared out between the two
    answers = [
        json.loads(line)
        for line in (run / "labels.jsonl").read_text().splitlines()
        if '"type": "answer"' in line
    ]
    authors = [answer["annotator"] for answer in answers]
    assert set(authors) == set(TEAM)  # both worked, each under their own name
    # the default overlap_until (50): every answer also asked of the other, beside the budget
    assert len(answers) == 20
    assert all(member.answered > 0 for member in members)
    metrics = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    sessions = [m for m in metrics if "crowd_seconds" in m]
    assert sessions, "no session's crowd measures were logged"
    assert all(f"crowd/{name}/reliability" in sessions[-1] for name in TEAM)
