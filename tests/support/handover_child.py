"""A team's session in a process of its own, for `test_crowd_races`: alice answers one
question and leaves, so her chain is handed over to bob; the process kills itself
(SIGKILL, nothing cleaned up) at the step of the hand-over named on its command line.

    python -m support.handover_child DIRECTORY withdrawn|continued|none|replay

`none` lets the session finish with bob alone, `replay` asks it again with nobody
answering (every answer must come back from the database); both print the session's
answers as JSON."""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
import time
from pathlib import Path

from seqrank.labelling.crowd_db import CrowdTables
from support.crowd import bare_team, team_request

PATIENCE = 0.5  # --reassign-after, in seconds


def kill_after(method: str, when) -> None:
    """SIGKILL this process right after `CrowdTables.<method>` returns what `when` accepts."""
    original = getattr(CrowdTables, method)

    def step(self, *args, **kwargs):
        result = original(self, *args, **kwargs)
        if when(result):
            os.kill(os.getpid(), signal.SIGKILL)
        return result

    setattr(CrowdTables, method, step)


def answer_as(tables: CrowdTables, name: str, choice: str, stop_after: int, done) -> None:
    answered = 0
    while answered < stop_after and not done.is_set():
        question = tables.claim(name)
        if question is None:
            time.sleep(0.01)
            continue
        tables.record_answer(question, choice, 5.0, name)
        answered += 1


def main() -> None:
    directory, step = Path(sys.argv[1]), sys.argv[2]
    if step == "withdrawn":  # the question is taken back; its chain not yet continued
        kill_after("withdraw_if_unanswered", lambda taken: taken)
    elif step == "continued":  # the continuation is stored; nothing of it asked yet
        kill_after("continue_chain", lambda chain: chain is not None)
    hub = bare_team(directory, ["alice", "bob"], PATIENCE)
    tables, done = hub.crowd.tables, threading.Event()

    def team() -> None:
        if step in ("withdrawn", "continued"):  # alice answers once, then leaves for good
            answer_as(tables, "alice", "left", 1, done)  # (bob comes once she has a chain)
        answer_as(tables, "bob", "right", 10**9, done)

    if step != "replay":
        threading.Thread(target=team, daemon=True).start()
    _, record = hub.source("offline", 0).ask_session(team_request("sequential", 8, 2))
    done.set()
    answers = [(a.first, a.second, a.answer.value, who) for a, who in
               zip(record.answers, record.crowd.answered_by, strict=True)]  # fmt: skip
    print(json.dumps(answers))
    hub.stop.set()
    hub.db.close()


if __name__ == "__main__":
    main()
