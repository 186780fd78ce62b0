"""A team's page restarted (issue 45, item 12): the time the server was down does not count
toward `--reassign-after`, so a question pending at the kill is still its annotator's after
the restart, and their answer is taken."""

from __future__ import annotations

import time

from seqrank.labelling.db import LabelDB
from support.crowd import TeamPage

TEAM = ["alice", "bob"]
PATIENCE = 5.0  # --reassign-after, in seconds
DOWNTIME = 3600.0  # how long the server was down: an hour


def shown_question(client) -> dict:
    for _ in range(600):
        state = client.get("/api/state").json()
        if state["status"] == "question":
            return state["question"]
        time.sleep(0.05)
    raise AssertionError("no question was shown")


def test_downtime_does_not_count_toward_the_hand_over(tmp_path):
    directory = tmp_path / "labels"
    page = TeamPage(directory, TEAM, "sequential", questions=4, overlap=0.0,
                    reassign_after=PATIENCE)  # fmt: skip
    try:
        pending = shown_question(page.client("alice"))  # alice holds it when the server dies
    finally:
        page.close()
    # the server stays down for an hour: the times stored before it are an hour in the past
    db = LabelDB.in_dir(directory)
    with db.transaction() as conn:
        conn.execute("UPDATE crowd_questions SET assigned_at = assigned_at - ?", (DOWNTIME,))
    db.close()

    page = TeamPage(directory, TEAM, "sequential", questions=4, overlap=0.0,
                    reassign_after=PATIENCE)  # fmt: skip
    try:
        alice = page.client("alice")
        assert shown_question(alice)["id"] == pending["id"]  # still hers after the restart
        time.sleep(1.0)  # she takes a second to answer, well within --reassign-after
        body = {"question_id": pending["id"], "choice": "left", "latency_ms": 900}
        reply = alice.post("/api/answer", json=body)
        assert reply.status_code == 200, reply.text
        assert not page.hub.crowd.tables.withdrawn(pending["id"])
        chains = page.hub.crowd.tables.chains("offline", 0)
        assert [c for c in chains if c.parent is not None] == []  # no chain was cut
        assert not page.errors
    finally:
        page.close()
