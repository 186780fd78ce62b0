"""`seqrank label study --finetune` as a user runs it: each method starts from a trained
run (supplementary Table 3), a scripted participant answers over HTTP."""

from __future__ import annotations

import json

from seqrank.cli import main
from seqrank.labelling.db import LabelDB
from support.pages import Participant, start_command


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
