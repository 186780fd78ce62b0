"""TensorBoard event files for every run, and `--wandb` in W&B's offline mode."""

from __future__ import annotations

import json

import pytest
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

from seqrank.cli import main
from seqrank.training.sinks import scalars, tag
from support.runs import resume_after_kill, run, tiny_config


def _events(directory):
    accumulator = EventAccumulator(str(directory))
    accumulator.Reload()
    return {name: accumulator.Scalars(name) for name in accumulator.Tags()["scalars"]}


def test_metric_names_are_grouped_and_text_is_left_out():
    assert tag("eval", "eval_return") == "eval/return"
    assert tag("feedback", "pairs_per_question") == "feedback/pairs_per_question"
    assert tag("feedback", "reward_heldout_accuracy") == "reward/heldout_accuracy"
    assert tag("train", "critic_loss") == "losses/critic"
    row = {"step": 5, "kind": "train", "phase": "pretrain", "alpha": 0.1, "x": None, "ok": True}
    assert scalars(row) == {"train/alpha": 0.1}


def test_every_run_writes_tensorboard_events_matching_its_metrics(tmp_path):
    trainer = run(tmp_path / "run", tiny_config(steps=2200, eval_every=1100, max_feedback=20))
    rows = trainer.run_dir.read_metrics()
    events = _events(tmp_path / "run")
    evals = [r for r in rows if r["kind"] == "eval"]
    assert [(e.step, e.value) for e in events["eval/return"]] == [
        (r["step"], pytest.approx(r["eval_return"])) for r in evals
    ]
    feedback = [r for r in rows if r["kind"] == "feedback"]
    assert [e.step for e in events["feedback/pairs_per_question"]] == [r["step"] for r in feedback]
    assert "reward/heldout_accuracy" in events and "losses/critic" in events


def test_a_resumed_run_has_each_step_once_in_tensorboard(tmp_path):
    resumed, _ = resume_after_kill(tmp_path, tiny_config())
    events = _events(tmp_path / "killed")
    steps = [e.step for e in events["losses/critic"]]
    assert steps == sorted(set(steps))  # the rows after the checkpoint were purged
    rows = resumed.run_dir.read_metrics()
    assert steps == [r["step"] for r in rows if r["kind"] == "train"]


@pytest.fixture
def wandb_offline(monkeypatch):
    pytest.importorskip("wandb")
    monkeypatch.setenv("WANDB_MODE", "offline")  # nothing leaves the machine
    monkeypatch.setenv("WANDB_SILENT", "true")


def test_wandb_gets_the_rows_under_the_same_names_against_the_env_step(tmp_path, wandb_offline):
    from seqrank.training.sinks import WandbSink

    sink = WandbSink("seqrank-test", tmp_path, {"task": "walker_walk"})
    sink.write({"step": 2000, "kind": "eval", "eval_return": 12.5, "total_asked": 40})
    sink.write({"step": 1500, "kind": "feedback", "pairs_per_question": 1.4, "kind2": "x"})
    summary = sink.run.summary
    assert summary["eval/return"] == 12.5 and summary["feedback/total_asked"] == 40
    assert summary["feedback/pairs_per_question"] == 1.4
    assert summary["env_step"] == 1500  # the last row's step, even when it is earlier
    sink.close()
    assert list(tmp_path.glob("wandb/offline-run-*/run-*.wandb"))


def test_wandb_option_logs_offline_and_a_resume_continues_the_same_run(tmp_path, wandb_offline):
    out = tmp_path / "run"
    short = ["--task", "dmc:cartpole_swingup", "--steps", "1100", "--seed-steps", "300"]
    small = ["--hidden", "32", "--batch", "32", "--eval-every", "1100", "--eval-episodes", "1"]
    args = ["train", *short, *small, "--reward", "true", "--device", "cpu", "--quiet"]
    assert main([*args, "--wandb", "seqrank-test", "--out", str(out)]) == 0
    saved = json.loads((out / "wandb.json").read_text())
    assert saved["project"] == "seqrank-test"
    assert json.loads((out / "meta.json").read_text())["wandb"] == "seqrank-test"
    (log,) = out.glob(f"wandb/offline-run-*-{saved['id']}/run-{saved['id']}.wandb")
    assert log.stat().st_size > 0
    assert main(["train", "--resume", str(out), "--quiet"]) == 0
    assert json.loads((out / "wandb.json").read_text())["id"] == saved["id"]  # the same run


def test_bad_wandb_options_are_named(tmp_path, capsys):
    assert main(["train", "--wandb", " ", "--out", str(tmp_path / "r"), "--quiet"]) == 2
    assert "--wandb needs a project name" in capsys.readouterr().err
