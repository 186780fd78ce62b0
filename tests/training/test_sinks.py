"""Metric names, and `--wandb` in W&B's offline mode (the TensorBoard files of real runs
are checked in test_training.py, on its runs)."""

from __future__ import annotations

import json

import pytest

from seqrank.cli import main
from seqrank.training.sinks import scalars, tag


def test_metric_names_are_grouped_and_text_is_left_out():
    assert tag("eval", "eval_return") == "eval/return"
    assert tag("feedback", "pairs_per_question") == "feedback/pairs_per_question"
    assert tag("feedback", "reward_heldout_accuracy") == "reward/heldout_accuracy"
    assert tag("train", "critic_loss") == "losses/critic"
    row = {"step": 5, "kind": "train", "phase": "pretrain", "alpha": 0.1, "x": None, "ok": True}
    assert scalars(row) == {"train/alpha": 0.1}


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
    (out / "summary.json").unlink()  # as if stopped after its last checkpoint
    assert main(["train", "--resume", str(out), "--quiet"]) == 0
    assert (out / "summary.json").exists()  # it was resumed, not left alone as finished
    assert json.loads((out / "wandb.json").read_text())["id"] == saved["id"]  # the same run
    assert len(list(out.glob(f"wandb/offline-run-*-{saved['id']}"))) >= 1


def test_bad_wandb_options_are_named(tmp_path, capsys):
    assert main(["train", "--wandb", " ", "--out", str(tmp_path / "r"), "--quiet"]) == 2
    assert "--wandb needs a project name" in capsys.readouterr().err
