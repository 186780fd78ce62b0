"""The SB3 examples run as a user runs them, at CI sizes; the labelling one is answered
through the page's HTTP API, as a person's browser would."""

from __future__ import annotations

import re
import subprocess
import sys
import threading
from pathlib import Path

import httpx

from seqrank.sb3 import PreferenceFeedback

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _run(*args: str, cwd: Path) -> str:
    done = subprocess.run(
        [sys.executable, *args], cwd=cwd, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_sac_on_walker_from_root_oracle_preferences(tmp_path):
    script = str(EXAMPLES / "sb3_sac_walker.py")
    printed = _run(script, "--steps", "1100", "--tiny", "--out", "walker", cwd=tmp_path)
    assert "asked 10, labelled pairs" in printed
    saved = PreferenceFeedback.load(tmp_path / "walker")
    assert saved.run.counters.asked == 10 and len(saved.labels) >= 10


def test_ppo_on_a_gymnasium_task_from_preferences(tmp_path):
    printed = _run(str(EXAMPLES / "sb3_ppo_gym.py"), "--steps", "1200", "--tiny", cwd=tmp_path)
    assert re.search(r"asked 20, inferred \d+; true return -?\d", printed), printed


def test_a_person_on_the_labelling_page_teaches_an_sb3_agent(tmp_path):
    args = [str(EXAMPLES / "sb3_human.py"), "--task", "dmc:cartpole_swingup", "--tiny"]
    process = subprocess.Popen(
        [sys.executable, *args, "--steps", "1200", "--port", "0", "--out", "run"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert process.stdout is not None
    url = re.search(r"labelling page: (http://\S+)", process.stdout.readline()).group(1)
    answered = []

    def person() -> None:  # answers every question "left" until training finishes
        while process.poll() is None:
            try:
                state = httpx.get(f"{url.rstrip('/')}/api/state", timeout=5).json()
            except httpx.HTTPError:
                return
            if state["status"] == "question":
                body = {"question_id": state["question"]["id"], "choice": "left", "latency_ms": 5}
                if httpx.post(f"{url.rstrip('/')}/api/answer", json=body).status_code == 200:
                    answered.append(body["question_id"])

    thread = threading.Thread(target=person, daemon=True)
    thread.start()
    out, err = process.communicate(timeout=600)
    assert process.returncode == 0, err
    assert "answered 4" in out and len(set(answered)) == 4
    assert (tmp_path / "run" / "labels" / "labels.sqlite").is_file()
    assert PreferenceFeedback.load(tmp_path / "run" / "feedback", label_dir=tmp_path / "x")
