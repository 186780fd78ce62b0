"""`seqrank train` with both QPA options on, PEBBLE and MRN: it trains, checkpoints, logs
the query window and the hybrid share, and a resumed run ends with the same numbers."""

from __future__ import annotations

from pathlib import Path

import pytest

from seqrank.cli import main
from seqrank.training.runs import RunDir
from support.runs import resume_after_kill, tiny_config, without_timing

# three sessions (steps 1200, 1700, 2200); a checkpoint at 2000 with hybrid replay on
QPA = {
    "steps": 2400,
    "max_feedback": 30,
    "eval_every": 2400,
    "query_episodes": 1,
    "hybrid_replay": 0.5,
    "hybrid_episodes": 1,
    "meta_update_frequency": 100,
}


# the values of `tiny_config` that differ from the small preset, as options
TINY = {
    "seed_steps": 300,
    "unsup_steps": 900,
    "feedback_frequency": 500,
    "reward_batch": 10,
    "hidden": 32,
    "batch": 32,
    "reward_hidden": 32,
    "reward_epochs": 5,
    "eval_episodes": 1,
    "checkpoint_every": 1000,
    "heldout_pairs": 50,
    "seed": 3,
}


def train(out: Path, **settings: object) -> RunDir:
    """`seqrank train` on the tiny settings and these."""
    argv = ["train", "--task", "dmc:cartpole_swingup", "--device", "cpu", "--quiet"]
    options = [f"--{k.replace('_', '-')}={v}" for k, v in {**TINY, **settings}.items()]
    assert main([*argv, "--out", str(out), *options]) == 0
    return RunDir.open(out)


@pytest.mark.parametrize("backbone", ["pebble", "mrn"])
def test_qpa_trains_checkpoints_and_resumes(backbone, tmp_path):
    directory = train(tmp_path / "cli", backbone=backbone, **QPA)
    config = tiny_config(backbone=backbone, **QPA)
    assert directory.read_config() == config
    rows = without_timing(directory.read_metrics())

    feedback = [r for r in rows if r["kind"] == "feedback"]
    assert len(feedback) == 3
    # an episode of cartpole ends every 1000 steps: each session cuts from the last one
    windows = [(r["query_first_episode"], r["query_last_episode"]) for r in feedback]
    assert windows == [(0, 0), (0, 0), (1, 1)]
    train_rows = [r for r in rows if r["kind"] == "train" and r["step"] > 1200]
    assert train_rows and all(r["hybrid_recent_share"] == 0.5 for r in train_rows)
    assert all(r["hybrid_window"] == 1000 for r in train_rows)  # one episode

    if backbone == "mrn":
        return  # resuming is the same code for both backbones: checked once, on pebble
    resumed, state = resume_after_kill(tmp_path / "killed", config, kill_at=2100)
    assert state["counters"]["step"] == 2000
    assert without_timing(resumed.run_dir.read_metrics()) == rows


def test_without_the_options_no_qpa_metrics_are_logged(tmp_path):
    rows = train(tmp_path / "plain", steps=1300, max_feedback=10, eval_every=1300).read_metrics()
    assert [r["kind"] for r in rows] == ["train", "feedback", "eval"]
    assert not any("query_first_episode" in r or "hybrid_window" in r for r in rows)
