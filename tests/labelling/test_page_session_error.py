"""An error inside a page session of `seqrank label online` ends the command in its one
line and exit code 2, after the page is stopped and the labels exported: the server and
clip-rendering threads are ended first (a GL context still current on a live thread when
the interpreter exited crashed the process, exit 139 / -11, after the error line)."""

from __future__ import annotations

import re
import sqlite3
import subprocess
import sys
import threading
import time

import httpx

from support.pages import TINY


def _start(args: list[str]) -> tuple[subprocess.Popen[str], str, list[str]]:
    """`seqrank ARGS`, the page address it printed and every stderr line (kept reading)."""
    process = subprocess.Popen(
        [sys.executable, "-m", "seqrank", *args],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
    )
    assert process.stderr is not None
    lines: list[str] = []
    for line in process.stderr:
        lines.append(line)
        found = re.search(r"labelling page: (http://\S+)", line)
        if found:
            threading.Thread(target=lambda: lines.extend(process.stderr), daemon=True).start()
            return process, found.group(1).rstrip("/"), lines
    process.kill()
    raise AssertionError(f"the server did not print its address: {''.join(lines)}")


def _first_question(url: str) -> dict:
    deadline = time.monotonic() + 600  # generous: a loaded 2-core machine is slow
    while time.monotonic() < deadline:
        state = httpx.get(f"{url}/api/state").json()
        if state["status"] == "question":
            return state["question"]
        time.sleep(0.1)
    raise AssertionError("the page never showed a question")


def test_an_error_in_a_page_session_exits_with_its_line_not_a_crash(tmp_path):
    run = tmp_path / "run"
    process, url, lines = _start(["label", "online", "--out", str(run), *TINY])
    try:
        question = _first_question(url)  # the session waits; its clips are being rendered
        # another program writes an answer the session cannot read: a real error in it
        with sqlite3.connect(run / "labels.sqlite", isolation_level=None) as other:
            other.execute(
                "INSERT INTO answers VALUES (?, 'left', 'bogus', 5.0, 'x', ?)",
                (question["id"], time.time()),
            )
        code = process.wait(300)
    finally:
        if process.poll() is None:
            process.kill()
    time.sleep(0.2)  # the reader thread takes the last lines
    stderr = "".join(lines)
    assert code == 2, f"exit code {code}; stderr:\n{stderr}"
    assert stderr.rstrip().splitlines()[-1] == "seqrank label: error: 'bogus' is not a valid Answer"
    assert "Traceback" not in stderr and "Fatal Python error" not in stderr
    assert (run / "labels.jsonl").exists()  # the export is written on the way out
