from __future__ import annotations

import json
import subprocess
import sys

import pytest

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
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    assert {r["kind"] for r in rows} == {"feedback", "eval", "train"}
    train_rows = [r for r in rows if r["kind"] == "train"]
    assert [r["phase"] for r in train_rows] == ["pretrain", "preference"]
    assert all(r["critic_loss"] >= 0 and r["alpha"] > 0 for r in train_rows)
    assert (out / "checkpoint.pt").exists() and (out / "returns.png").exists()
    printed = capsys.readouterr().out
    assert "questions asked" in printed and "evaluation return by step" in printed
    # a finished run resumes from its last checkpoint and ends with the same summary
    summary = json.loads((out / "summary.json").read_text())
    assert main(["train", "--resume", str(out), "--quiet"]) == 0
    again = json.loads((out / "summary.json").read_text())
    assert again["eval_curve"] == summary["eval_curve"] and again["asked"] == 20


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


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "seqrank", "train", *args],
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--task", "walker"], "unknown task 'walker'; accepted: walker_walk, cheetah_run"),
        (["--scheme", "tree"], "unknown scheme 'tree'; accepted: pairwise, sequential, root"),
        (["--teacher", "perfect"], "unknown teacher 'perfect'; accepted: oracle, mistake"),
        (["--backbone", "ppo"], "unknown backbone 'ppo'; accepted: pebble, mrn"),
        (["--selection", "best"], "unknown selection 'best'; accepted: uniform"),
        (["--scale", "huge"], "invalid choice: 'huge'"),
        (["--device", "tpu"], "unknown device 'tpu'; accepted: auto, cpu, cuda"),
        (["--max-feedback", "100000", "--reward-batch", "10"], "impossible budget"),
        (["--reward-batch", "500", "--max-feedback", "100"], "exceeds max_feedback"),
        (["--steps", "-5"], "steps must be a whole number from 1 to 2147483647, got -5"),
        (["--hidden", "big"], "argument --hidden: invalid int value: 'big'"),
        (["--resume", "/nonexistent/run"], "no run directory at /nonexistent/run"),
        (["--path", "quick"], "unknown path 'quick'; accepted: auto, reference, fast"),
        (["--precision", "fp16"], "unknown precision 'fp16'; accepted: auto, fp32, tf32, bf16"),
    ],
)
def test_bad_input_is_one_clear_line_and_exit_code_2(args, message):
    pinned = "--device" in args or "--resume" in args
    result = run_cli(*args) if pinned else run_cli(*args, "--device", "cpu")
    assert result.returncode == 2, result.stderr
    assert message in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_a_precision_the_path_lacks_is_refused_before_anything_is_written(tmp_path):
    # on a CPU, path auto is the reference, which is strict fp32
    result = run_cli("--device", "cpu", "--precision", "tf32", "--out", str(tmp_path / "run"))
    assert result.returncode == 2
    assert "precision 'tf32' needs the fast path" in result.stderr
    assert not (tmp_path / "run").exists()


def test_resume_refuses_new_settings_and_create_refuses_a_used_directory(tmp_path):
    (tmp_path / "config.json").write_text("{}")
    result = run_cli("--resume", str(tmp_path), "--steps", "10")
    assert result.returncode == 2 and "drop --steps" in result.stderr
    result = run_cli("--out", str(tmp_path), "--device", "cpu")
    assert result.returncode == 2 and "is not empty; resume it with --resume" in result.stderr


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
