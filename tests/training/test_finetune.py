"""Fine-tuning a saved run (the user study's first kind, supplementary Table 3)."""

from __future__ import annotations

import json

import pytest
import torch

from seqrank.config import resolve_config
from seqrank.training.finetune import FINETUNE_PRESET, PARTS
from support.runs import run, tiny_config

SIZES = dict(hidden=32, batch=32, reward_hidden=32, device="cpu")


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    folder = tmp_path_factory.mktemp("source") / "run"
    run(folder, tiny_config(reward="true", steps=1600, eval_every=800))
    return folder


def finetune_config(source, **overrides):
    values = {**FINETUNE_PRESET, **SIZES, "eval_episodes": 1, "reward_epochs": 3}
    values.update(start_from=str(source), heldout_pairs=10, **overrides)
    return resolve_config("dmc:cartpole_swingup", "small", values)


def test_a_run_starts_from_the_saved_agent_and_buffer_and_asks_per_part(tmp_path, source):
    saved = torch.load(source / "checkpoint.pt", weights_only=False)
    trainer = run(tmp_path / "tuned", finetune_config(source, parts="low,varied"))
    assert trainer.counters.asked == 20 and trainer.counters.sessions == 2  # Table 3
    assert len(trainer.replay) == saved["replay"]["size"] + 400  # kept, then 400 more steps
    # learning rate 1e-8: the actor is still the saved one, to float rounding
    before, after = saved["agent"]["actor"], trainer.agent.state_dict()["actor"]
    assert all(torch.allclose(before[k], after[k], atol=1e-5) for k in before)
    # the last session cut its segments from the 'varied' part's episodes
    assert len(trainer.episodes) == len(PARTS["varied"])


def test_starting_from_a_run_of_another_task_or_size_is_refused(tmp_path, source):
    with pytest.raises(ValueError, match=r"hidden 32.*this run 64"):
        finetune_config(source, hidden=64)
    with pytest.raises(ValueError, match="not a run directory with a checkpoint"):
        finetune_config(tmp_path)
    with pytest.raises(ValueError, match="parts 'lowest'"):
        finetune_config(source, parts="lowest")
    assert json.loads((source / "config.json").read_text())["reward"] == "true"
