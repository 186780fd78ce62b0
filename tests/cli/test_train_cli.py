from __future__ import annotations

import json

import torch

import seqrank
from seqrank.cli import main

TINY = [
    "--task",
    "dmc:cartpole_swingup",
    "--steps",
    "2200",
    "--seed-steps",
    "300",
    "--unsup-steps",
    "900",
    "--feedback-frequency",
    "500",
    "--max-feedback",
    "20",
    "--reward-batch",
    "10",
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


def test_train_writes_a_self_describing_run_directory(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", *TINY, "--out", str(out), "--quiet"]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["task"] == "dmc:cartpole_swingup" and config["hidden"] == 32
    assert config["scale"] == "small" and config["reward_layers"] == 3  # preset values kept
    meta = json.loads((out / "meta.json").read_text())
    assert meta["seed"] == 0 and meta["packages"]["torch"] and "git_revision" in meta
    assert meta["cpu"]["model"] and set(meta["cpu"]["flags"]) <= {
        "avx2", "avx512f", "avx512_bf16", "amx_bf16"
    }  # fmt: skip
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert {r["kind"] for r in rows} == {"feedback", "eval", "train"}
    train_rows = [r for r in rows if r["kind"] == "train"]
    assert [r["phase"] for r in train_rows] == ["pretrain", "preference"]
    assert all(r["critic_loss"] >= 0 and r["alpha"] > 0 for r in train_rows)
    assert (out / "checkpoint.pt").exists() and (out / "returns.png").exists()
    printed = capsys.readouterr().out
    assert "questions asked" in printed and "evaluation return by step" in printed
    # resuming a finished run says so and changes nothing
    before = stamps(out)
    assert main(["train", "--resume", str(out), "--quiet"]) == 0
    assert "is finished (2,200 steps, summary.json); nothing to resume" in capsys.readouterr().err
    assert stamps(out) == before
    # the final policy is saved: the checkpoint of the last step, loadable and acting
    run = seqrank.load_run(out)
    assert torch.load(out / "checkpoint.pt", weights_only=False)["counters"]["step"] == 2200
    observation = run.environment().reset(seed=0)[0]
    action = run.policy().act(observation, True, torch.Generator())
    assert action.shape == (1,) and abs(float(action[0])) <= 1.0


def stamps(folder):
    """Each file's modification time, but the lock's (it holds the pid of its last holder)."""
    return {p.name: p.stat().st_mtime_ns for p in folder.iterdir() if p.name != ".lock"}


def test_the_true_reward_baseline_is_one_option_and_says_what_it_is(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    short = ["--task", "dmc:cartpole_swingup", "--steps", "1100", "--seed-steps", "300"]
    small = ["--hidden", "32", "--batch", "32", "--eval-every", "1100", "--eval-episodes", "1"]
    assert main(["train", *short, *small, "--device", "cpu", "--reward", "true", "--quiet"]) == 0
    (run_dir,) = (tmp_path / "seqrank-out" / "runs").iterdir()
    assert run_dir.name.startswith("dmc-cartpole_swingup_true-reward_seed0_")
    printed = capsys.readouterr().out
    assert "the true-reward baseline (no feedback)" in printed
    assert json.loads((run_dir / "summary.json").read_text())["reward"] == "true"


def test_resume_refuses_new_settings_and_create_refuses_a_used_directory(tmp_path, capsys):
    (tmp_path / "config.json").write_text("{}")
    assert main(["train", "--resume", str(tmp_path), "--steps", "10"]) == 2
    assert "drop --steps" in capsys.readouterr().err
    assert main(["train", "--out", str(tmp_path), "--device", "cpu"]) == 2
    assert "is not empty; resume it with --resume" in capsys.readouterr().err


def test_resume_before_the_first_checkpoint_starts_over_cleanly(tmp_path):
    out = tmp_path / "run"
    args = [*TINY, "--steps", "1700", "--max-feedback", "10", "--checkpoint-every", "100000"]
    assert main(["train", *args, "--out", str(out), "--quiet"]) == 0
    first = rows_without_timing(out)
    # a finished run checkpoints its last step; without it, it is a run killed before its
    # first checkpoint
    (out / "checkpoint.pt").unlink()
    assert main(["train", "--resume", str(out), "--quiet"]) == 0
    assert rows_without_timing(out) == first  # the same rows, none twice


def rows_without_timing(out):
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    timing = {"steps_per_second", "wall_seconds"}
    return [{k: v for k, v in row.items() if k not in timing} for row in rows]
