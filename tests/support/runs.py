"""Tiny training runs, killed and resumed, and learnable preference data."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from seqrank.config import resolve_config
from seqrank.training.runs import RunDir
from seqrank.training.trainer import Trainer

TIMING = {"steps_per_second", "wall_seconds"}


def tiny_config(**overrides):
    values = dict(
        steps=3200,
        seed_steps=300,
        unsup_steps=900,
        feedback_frequency=500,
        max_feedback=30,
        reward_batch=10,
        hidden=32,
        layers=2,
        batch=32,
        reward_hidden=32,
        reward_epochs=5,
        eval_every=1600,
        eval_episodes=1,
        checkpoint_every=1000,
        heldout_pairs=50,
        device="cpu",
        seed=3,
    )
    values.update(overrides)
    return resolve_config("dmc:cartpole_swingup", "small", values)


def run(path: Path, config, stop_at: int | None = None) -> Trainer:
    trainer = Trainer(config, RunDir.create(path, config, "cpu"))
    if stop_at is not None:

        def kill(step, live):
            if step >= stop_at:
                raise KeyboardInterrupt

        trainer.progress = kill
    trainer.train()
    return trainer


def without_timing(rows):
    return [{k: v for k, v in row.items() if k not in TIMING} for row in rows]


def resume_after_kill(
    tmp_path: Path, config, kill_at: int = 2500, checkpoint: int = 2000
) -> tuple[Trainer, dict]:
    """A run killed at step `kill_at`, resumed from its `checkpoint` step to the end."""
    with pytest.raises(KeyboardInterrupt):
        run(tmp_path / "killed", config, stop_at=kill_at)
    directory = RunDir.open(tmp_path / "killed")
    state = directory.load_checkpoint()
    assert state is not None and state["counters"]["step"] == checkpoint
    resumed = Trainer(directory.read_config(), directory)
    resumed.load_checkpoint(state)
    resumed.train()
    return resumed, state


def segment_pairs(count: int, seed: int = 0):
    """Segments whose true return is the sum of feature 0: a learnable preference."""
    gen = torch.Generator().manual_seed(seed)
    segments = torch.randn(2 * count, 10, 3, generator=gen)
    returns = segments[:, :, 0].sum(1)
    first, second = torch.arange(0, 2 * count, 2), torch.arange(1, 2 * count, 2)
    labels = (returns[first] > returns[second]).float()
    return segments, first, second, labels
