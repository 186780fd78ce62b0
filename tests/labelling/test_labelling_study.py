"""`seqrank label study` and `seqrank label online` as a user runs them, with a scripted
participant answering over HTTP; then `seqrank study-report`."""

from __future__ import annotations

import json

from seqrank.cli import main
from seqrank.labelling.db import LabelDB
from support.pages import TINY, Participant, start_command


def test_study_runs_three_methods_with_surveys_and_reports(tmp_path):
    study = tmp_path / "study"
    for participant, scores in (("p1", [2, 5]), ("p2", [4, 1])):
        args = ["label", "study", "--participant", participant, "--study-dir", str(study), *TINY]
        args += ["--methods", "pairwise,root"]
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
    assert set(report["methods"]) == {"pairwise", "root"}
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
