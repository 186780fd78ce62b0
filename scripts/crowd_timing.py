"""How long a labelling session takes a team (issue 37, item 5): simulated annotators
answering over the page's HTTP API at a fixed pace, 1, 2 and 4 of them, each session
timed from its first question to its last answer (the driver's own measure).

    python scripts/crowd_timing.py --out results/crowd/timing.json

Each annotator polls `/api/state` with their own token, waits `--pace` seconds (the time a
person takes to watch and decide) and posts an answer; the page is the real app (FastAPI's
test client, no browser), the driver is `seqrank label offline`'s with random-action
episodes of dmc:cartpole_swingup.
"""

from __future__ import annotations

import argparse
import json
import random
import statistics
import tempfile
import threading
import time
from pathlib import Path

from fastapi.testclient import TestClient

from seqrank.labelling.app import OfflineOptions, ServerOptions, open_hub, run_offline
from seqrank.labelling.crowd_team import open_team
from seqrank.labelling.page_state import Phase
from seqrank.labelling.server import create_app

TASK = "dmc:cartpole_swingup"
NAMES = ["ann", "ben", "cat", "dan"]


def one_session(people: int, scheme: str, questions: int, pace: float, seed: int) -> dict:
    directory = Path(tempfile.mkdtemp(prefix="crowd-timing-"))
    hub = open_hub(directory, TASK, ServerOptions(countdown_s=0.0))
    team = NAMES[:people]
    open_team(hub, team, 0.1, 60.0)
    options = OfflineOptions(TASK, scheme, questions, 1, 50, 1, seed, None, "full", tuple(team))
    done = threading.Event()
    answers: dict[str, int] = dict.fromkeys(team, 0)
    sessions: list[float] = []

    def drive() -> None:
        original = hub.state.move

        def spy(phase: Phase | str, message: str) -> None:
            if phase == Phase.ASKING:  # a team's session starts asking
                sessions.append(time.monotonic())
            original(phase, message)

        hub.state.move = spy  # type: ignore[method-assign]
        run_offline(directory, options, hub, lambda text: None)
        sessions.append(time.monotonic())
        done.set()

    def answer(name: str) -> None:
        client = TestClient(create_app(hub), base_url="http://127.0.0.1:8765")
        client.headers["X-Seqrank-Token"] = hub.crowd.tokens[name]
        rng = random.Random(name)
        while not done.is_set():
            state = client.get("/api/state").json()
            if state["status"] != "question":
                time.sleep(0.01)
                continue
            time.sleep(pace)
            body = {
                "question_id": state["question"]["id"],
                "choice": rng.choice(["left", "right"]),
                "latency_ms": pace * 1000,
            }
            if client.post("/api/answer", json=body).status_code == 200:
                answers[name] += 1

    threads = [threading.Thread(target=answer, args=(n,), daemon=True) for n in team]
    for thread in threads:
        thread.start()
    drive()
    for thread in threads:
        thread.join(5)
    hub.stop.set()
    assert hub.renderer is not None
    hub.renderer.close()
    hub.db.close()
    return {"people": people, "seconds": sessions[-1] - sessions[0], "answers": answers}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--scheme", default="sequential")
    parser.add_argument("--questions", type=int, default=24)
    parser.add_argument("--pace", type=float, default=1.0, help="seconds an answer")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    runs = []
    for people in (1, 2, 4):
        for seed in range(args.repeats):
            run = one_session(people, args.scheme, args.questions, args.pace, seed)
            runs.append(run)
            print(json.dumps(run), flush=True)
    summary = {}
    for people in (1, 2, 4):
        times = [r["seconds"] for r in runs if r["people"] == people]
        summary[str(people)] = {"median_s": statistics.median(times), "runs_s": times}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    record = {"settings": vars(args) | {"out": str(args.out)}, "runs": runs, "summary": summary}
    args.out.write_text(json.dumps(record, indent=2) + "\n")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
