"""`seqrank label study` and `seqrank label online` as a user runs them, with a scripted
participant answering over HTTP; then `seqrank study-report`."""

from __future__ import annotations

import json
import threading
import time

import httpx

from seqrank.cli import main
from seqrank.labelling.db import LabelDB
from support.pages import start_command

TINY = [
    "--task", "dmc:cartpole_swingup", "--steps", "1800", "--seed-steps", "300",
    "--unsup-steps", "900", "--feedback-frequency", "500", "--max-feedback", "10",
    "--reward-batch", "5", "--hidden", "32", "--batch", "32", "--reward-hidden", "32",
    "--reward-epochs", "5", "--eval-every", "900", "--eval-episodes", "1",
    "--heldout-pairs", "50", "--device", "cpu", "--countdown", "0", "--port", "0",
]  # fmt: skip


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


def test_study_runs_three_methods_with_surveys_and_reports(tmp_path):
    study = tmp_path / "study"
    for participant, scores in (("p1", [2, 3, 5]), ("p2", [1, 4, 4])):
        args = ["label", "study", "--participant", participant, "--study-dir", str(study), *TINY]
        process, url = start_command(args)
        helper = Participant(url, scores)
        helper.start()
        try:
            assert process.wait(900) == 0  # generous: a loaded 2-core machine is slow
        finally:
            helper.halt.set()
            if process.poll() is None:
                process.kill()
        order = json.loads((study / participant / "study.json").read_text())["order"]
        db = LabelDB.in_dir(study / participant)
        surveys = {s["run"]: s["satisfaction"] for s in db.surveys()}
        assert surveys == dict(zip(order, scores, strict=True))  # in the order they were used
        for method in order:
            summary = json.loads((study / participant / method / "summary.json").read_text())
            assert summary["scheme"] == method and summary["asked"] == 10
            assert len(db.answered_questions(method)) == 10
        db.close()
    orders = [json.loads((study / p / "study.json").read_text())["order"] for p in ("p1", "p2")]
    assert orders[0] != orders[1]  # counterbalanced
    assert main(["study-report", str(study), "--json", str(tmp_path / "report.json")]) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    assert set(report["methods"]) == {"pairwise", "sequential", "root"}
    assert all(report["methods"][m]["reward"]["n"] == 2 for m in report["methods"])
    assert {t["n"] for t in report["tests"]} == {2}


def test_online_labelling_trains_and_resumes_from_the_command_line(tmp_path):
    run = tmp_path / "run"
    process, url = start_command(["label", "online", "--out", str(run), *TINY])
    helper = Participant(url, [])
    helper.start()
    try:
        assert process.wait(900) == 0  # generous: a loaded 2-core machine is slow
    finally:
        helper.halt.set()
    summary = json.loads((run / "summary.json").read_text())
    assert summary["teacher"] == "human" and summary["asked"] == 10
    exported = (run / "labels.jsonl").read_text()
    assert exported.count('"type": "answer"') == 10


def test_the_fine_tuning_study_starts_each_method_from_a_trained_run(tmp_path):
    sizes = ["--hidden", "32", "--batch", "32", "--reward-hidden", "32", "--device", "cpu"]
    source = tmp_path / "trained"
    trained = ["train", "--task", "dmc:cartpole_swingup", "--reward", "true", "--steps", "1000"]
    trained += ["--eval-every", "1000", "--eval-episodes", "1", "--out", str(source), "--quiet"]
    assert main([*trained, *sizes]) == 0
    study = tmp_path / "study"
    args = ["label", "study", "--participant", "p1", "--study-dir", str(study), "--finetune"]
    args += ["--start-from", str(source), "--parts", "low,varied", "--methods", "root"]
    args += ["--task", "dmc:cartpole_swingup", "--eval-episodes", "1", "--reward-epochs", "3"]
    args += ["--heldout-pairs", "20", "--countdown", "0", "--port", "0", "--size", "64", *sizes]
    process, url = start_command(args)
    helper = Participant(url, [4])
    helper.start()
    try:
        assert process.wait(900) == 0
    finally:
        helper.halt.set()
        if process.poll() is None:
            process.kill()
    db = LabelDB.in_dir(study / "p1")
    for method in ("root",):
        config = json.loads((study / "p1" / method / "config.json").read_text())
        assert (config["steps"], config["actor_lr"], config["segment_length"]) == (400, 1e-8, 30)
        summary = json.loads((study / "p1" / method / "summary.json").read_text())
        assert summary["asked"] == 20 and summary["sessions"] == 2  # Table 3: 20 answers
        assert len(db.answered_questions(method)) == 20
    assert {s["run"] for s in db.surveys()} == {"root"}
    db.close()
