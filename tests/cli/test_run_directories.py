"""Run directories never leave a user stuck: one process per directory (a killed holder's
lock is taken over), a failed start leaves nothing, SIGTERM stops a run at its next episode
end with a checkpoint, a finished run is not run again, and its labels export."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from seqrank.cli import main
from seqrank.feedback.label_file import read_label_file
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.replay import ReplaySource
from seqrank.training.launch import start_new
from seqrank.training.runs import RunDir
from support.runs import tiny_config

# 1 500 steps: warm-up 300, pre-training to 1 000 (the first episode's end), sessions of 5
# questions at steps 1 000 and 1 250
SHORT = [
    "--task", "dmc:cartpole_swingup", "--steps", "1500", "--seed-steps", "300",
    "--unsup-steps", "700", "--feedback-frequency", "250", "--max-feedback", "10",
    "--reward-batch", "5", "--hidden", "32", "--batch", "32", "--reward-hidden", "32",
    "--reward-epochs", "5", "--eval-every", "1500", "--eval-episodes", "1",
    "--checkpoint-every", "100000", "--heldout-pairs", "50", "--device", "cpu", "--quiet",
]  # fmt: skip


def seqrank_process(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "seqrank", *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "OMP_NUM_THREADS": "1", "COLUMNS": "200"},
    )


def wait_for_line(process: subprocess.Popen[str], text: str, seconds: float = 120) -> str:
    assert process.stderr is not None
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        line = process.stderr.readline()
        if text in line:
            return line
        if not line and process.poll() is not None:
            break
    process.kill()
    raise AssertionError(f"never printed {text!r}")


def finished_looking_run(path: Path) -> None:
    """A run directory with its summary (no training needed to resume-check it)."""
    run = RunDir.create(path, tiny_config(), "cpu")
    run.write_summary({"steps": 3200})
    run.release()


def test_one_process_per_run_directory_and_a_killed_holder_is_taken_over(tmp_path, capsys):
    path = tmp_path / "run"
    finished_looking_run(path)
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time; from seqrank.dirs import DirLock; "
            "DirLock(sys.argv[1], 'run directory').acquire(); print('held', flush=True); "
            "time.sleep(600)",
            str(path),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        assert main(["train", "--resume", str(path)]) == 2
        err = capsys.readouterr().err
        assert (
            f"run directory {path} is in use by another seqrank process (pid {holder.pid})" in err
        )
        assert len(err.strip().splitlines()) == 1
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait(10)
    # the kernel dropped the killed holder's lock: the next command takes the directory
    assert main(["train", "--resume", str(path)]) == 0
    assert "is finished" in capsys.readouterr().err


def test_a_start_that_fails_leaves_nothing(tmp_path):
    def out_of_memory(config, run):
        raise RuntimeError("DefaultCPUAllocator: can't allocate memory: you tried to allocate "
                           "56000000000000 bytes. Error code 12")  # fmt: skip

    path = tmp_path / "a" / "b" / "run"
    with pytest.raises(ValueError, match=r"need more memory than there is \(52,154.1 GiB"):
        start_new(path, tiny_config(), "cpu", out_of_memory)
    assert list(tmp_path.iterdir()) == []  # the run directory and the folders made for it


@pytest.mark.parametrize("given", ["new", "empty"])
def test_a_second_ctrl_c_while_the_trainer_is_built_says_it_removed_the_run(
    given, tmp_path, monkeypatch, capsys
):
    """Before step 0 there is nothing to resume: a second Ctrl-C while the environment,
    agent and reward model are built removes the new run directory again (and the folders
    made for it; an empty folder given is kept), and one line says so (it was silent)."""
    from seqrank.training import trainer

    def interrupted(*args, **kwargs):
        signal.raise_signal(signal.SIGINT)  # the first: stop cleanly once training runs
        signal.raise_signal(signal.SIGINT)  # the second: at once
        raise AssertionError("a second Ctrl-C interrupts")

    monkeypatch.setattr(trainer, "make_agent", interrupted)
    out = tmp_path / "runs" / "run"
    if given == "empty":
        out.mkdir(parents=True)
    assert main(["train", *SHORT, "--out", str(out)]) == 130
    err = capsys.readouterr().err
    kept = " (the empty folder given is kept)" if given == "empty" else ""
    removed = f"interrupted while preparing the run, before training began: removed {out}{kept}"
    assert err.splitlines() == [
        "Ctrl-C: stopping cleanly (saving first; Ctrl-C again stops at once)",
        removed,
    ]
    if given == "empty":
        assert list(out.iterdir()) == []
    else:
        assert list(tmp_path.iterdir()) == []


def test_dry_run_checks_and_writes_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["train", *SHORT, "--dry-run"]) == 0
    err = capsys.readouterr().err
    assert "settings valid (small preset, device cpu)" in err and "max_feedback = 10" in err
    threads = torch.get_num_threads()  # the reference path keeps torch's setting
    assert f"fp32, {threads} torch thread" in err
    assert list(tmp_path.iterdir()) == []


def test_sigterm_stops_at_the_episode_end_with_a_checkpoint_and_resume_finishes(tmp_path, capsys):
    out = tmp_path / "run"
    process = seqrank_process("train", *SHORT, "--out", str(out))
    wait_for_line(process, "run directory:")
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=300)
    assert process.returncode == 128 + signal.SIGTERM, err
    assert "SIGTERM: stopping cleanly" in err
    assert (
        f"stopped at step 1,000, checkpoint saved; continue with: seqrank train --resume {out}"
        in err
    )
    assert "Traceback" not in err
    state = torch.load(out / "checkpoint.pt", weights_only=False)
    assert state["counters"]["step"] == 1000 and not (out / "summary.json").exists()

    assert main(["train", "--resume", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 1500 and summary["asked"] == 10
    # a scripted run's labels export like a labelling directory's, and replay as they were
    exported = tmp_path / "labels.jsonl"
    assert main(["labels", "export", str(out), "-o", str(exported)]) == 0
    assert "10 answers of run" in capsys.readouterr().out
    labels = read_label_file(exported)
    assert labels.header["task"] == "dmc:cartpole_swingup" and labels.header["obs_dim"] == 5
    store = LabelStore()
    store.load_state_dict(torch.load(out / "checkpoint.pt", weights_only=False)["labels"])
    assert [a["answer"] for a in labels.answers] == [row[4] for row in store.asked]
    assert {a["scheme"] for a in labels.answers} == {"sequential"}
    replay = ReplaySource(labels, str(exported))
    assert [s for _, s in replay.sessions] == [0, 1]
    first = labels.segments[labels.answers[0]["first"]]
    assert sum(first["rewards"]) == pytest.approx(store.segment_returns[0], rel=1e-5)


@pytest.mark.parametrize("native", [True, False])
def test_bf16_asked_for_on_a_cpu_without_native_bf16_is_said_to_be_slow(
    native, tmp_path, monkeypatch, capsys
):
    from seqrank.training import cpu_path

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cpu_path, "native_bf16", lambda: native)
    assert main(["train", *SHORT, "--path", "fast", "--precision", "bf16", "--dry-run"]) == 0
    err = capsys.readouterr().err.replace("\n", " ")
    assert "fast path, bf16" in err
    assert ("this CPU has no native bf16" in err) is not native
    assert "--precision fp32 (or auto) trains faster" in err or native
