"""`--teacher replay:FILE`: a run takes the settings its label file recorded and records
those, wherever the teacher is given (command line, Python API, sweep files); settings
given otherwise are refused (their rows are in test_bad_input.py)."""

from __future__ import annotations

import json

import pytest

import seqrank
from seqrank.cli import main
from support.labels import TASK, write_labels

# TINY of test_train_cli.py less the task and the budget, which the label file gives
TINY = [
    "--steps",
    "2200",
    "--seed-steps",
    "300",
    "--unsup-steps",
    "900",
    "--feedback-frequency",
    "500",
    "--hidden",
    "32",
    "--batch",
    "32",
    "--reward-hidden",
    "32",
    "--reward-epochs",
    "5",
    "--eval-every",
    "1100",
    "--eval-episodes",
    "1",
    "--checkpoint-every",
    "1000",
    "--heldout-pairs",
    "50",
    "--device",
    "cpu",
]


def test_a_replayed_run_takes_and_records_the_settings_of_its_label_file(tmp_path, capsys):
    """Root answers in two sessions of 4 on 20-step segments: the run (no --task, --scheme,
    --segment-length or budget given) uses them and its config.json and summary say so,
    where the defaults are walker_walk, sequential, 50 steps and the preset's budget."""
    labels = write_labels(tmp_path / "labels.jsonl", scheme="root", segment_length=20)
    out = tmp_path / "run"
    assert (
        main(["train", *TINY, "--teacher", f"replay:{labels}", "--out", str(out), "--quiet"]) == 0
    )
    config = json.loads((out / "config.json").read_text())
    recorded = {"task": TASK, "scheme": "root", "segment_length": 20}
    assert {k: config[k] for k in recorded} == recorded
    assert (config["reward_batch"], config["max_feedback"]) == (4, 8)
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["scheme"], summary["sessions"], summary["asked"]) == ("root", 2, 8)
    assert f"{TASK}: root scheme, replay:{labels} teacher" in capsys.readouterr().out


def test_a_budget_that_ends_within_a_recorded_session_replays_its_first_answers(tmp_path):
    labels = write_labels(tmp_path / "labels.jsonl", sessions=(4, 4))
    out = tmp_path / "run"
    args = ["train", *TINY, "--task", TASK, "--teacher", f"replay:{labels}", "--max-feedback", "6"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["sessions"], summary["asked"]) == (2, 6)


def test_dry_run_prints_the_settings_taken_from_the_label_file(tmp_path, capsys):
    labels = write_labels(tmp_path / "labels.jsonl", scheme="root", segment_length=20)
    out = tmp_path / "run"
    args = ["train", "--device", "cpu", "--task", TASK, "--teacher", f"replay:{labels}"]
    assert main([*args, "--out", str(out), "--dry-run"]) == 0
    printed = capsys.readouterr().err.splitlines()
    for name, value in {"task": TASK, "scheme": "root", "segment_length": 20}.items():
        assert f"  {name} = {value}" in printed
    assert not out.exists()


def test_the_api_takes_the_label_files_settings_and_refuses_others(tmp_path):
    labels = write_labels(tmp_path / "labels.jsonl", segment_length=20)
    config = seqrank.make_config(teacher=f"replay:{labels}")
    assert (config.task, config.scheme, config.segment_length) == (TASK, "sequential", 20)
    with pytest.raises(ValueError) as raised:
        seqrank.make_config(teacher=f"replay:{labels}", scheme="root")
    assert str(raised.value) == (
        f"scheme root conflicts with the replay file's scheme sequential ({labels}); "
        "leave scheme out to take the file's"
    )


def test_a_sweep_of_a_replay_teacher_refuses_a_scheme_axis_the_file_contradicts(tmp_path, capsys):
    labels = write_labels(tmp_path / "labels.jsonl")
    spec = tmp_path / "sweep.toml"
    spec.write_text(
        f'tasks = ["{TASK}"]\nschemes = ["sequential", "root"]\n'
        f'teachers = ["replay:{labels}"]\nout = "{tmp_path / "sweep-out"}"\ndevice = "cpu"\n'
    )
    assert main(["sweep", str(spec), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "scheme root conflicts with the replay file's scheme sequential" in err
    assert not (tmp_path / "sweep-out").exists()
