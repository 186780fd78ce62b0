"""The baselines: the true-reward agent and the no-feedback floor (`--reward true|none`)."""

from __future__ import annotations

import pytest
import torch

from seqrank.buffer import ReplayBuffer
from seqrank.config import resolve_config
from support.runs import run, tiny_config


def test_the_buffer_hands_out_the_column_it_trains_on():
    for train_on, expected in (("reward", 2.0), ("true_reward", 1.0)):
        buffer = ReplayBuffer(4, 2, 1, torch.device("cpu"), train_on=train_on)
        buffer.add_transition([0.0, 0.0], [0.0], 1.0, [0.0, 0.0], False, None)
        buffer.reward[0] = 2.0
        batch = buffer.sample(3, torch.Generator().manual_seed(0))
        assert batch.reward.flatten().tolist() == [expected] * 3
    with pytest.raises(ValueError, match="train_on 'learned'; accepted: reward, true_reward"):
        ReplayBuffer(4, 2, 1, torch.device("cpu"), train_on="learned")


def test_a_true_reward_run_asks_nothing_skips_pretraining_and_learns_the_true_reward(tmp_path):
    trainer = run(tmp_path / "true", tiny_config(reward="true", steps=1600))
    rows = trainer.run_dir.read_metrics()
    assert not [r for r in rows if r["kind"] == "feedback"]
    assert {r["phase"] for r in rows if r["kind"] == "train"} == {"true-reward"}
    summary = trainer.run_dir.read_summary()
    assert summary["reward"] == "true" and summary["asked"] == 0
    assert summary["scheme"] is None and summary["teacher"] is None  # it asked no one
    # the learned column was never filled: the agent trained on the true one
    assert float(trainer.replay.reward.abs().sum()) == 0.0
    assert float(trainer.replay.true_reward.abs().sum()) > 0.0


def test_a_no_feedback_run_pretrains_then_learns_the_untrained_reward_model(tmp_path):
    config = tiny_config(reward="none", steps=2000, eval_every=1000)
    trainer = run(tmp_path / "none", config)
    rows = trainer.run_dir.read_metrics()
    assert not [r for r in rows if r["kind"] == "feedback"]
    phases = [r["phase"] for r in rows if r["kind"] == "train"]
    assert phases == ["pretrain", "no-feedback"]
    # every stored transition carries the untrained model's reward
    size = len(trainer.replay)
    obs, action = trainer.replay.obs[:size], trainer.replay.action[:size]
    expected = trainer.reward_model.reward(obs, action)
    assert torch.allclose(trainer.replay.reward[:size], expected, atol=1e-6)


def test_the_block_task_has_a_true_reward_dqn_baseline(tmp_path):
    overrides = dict(steps=1200, eval_every=600, eval_episodes=2, device="cpu", hidden=32)
    config = resolve_config("block:place", "small", {"reward": "true", **overrides})
    trainer = run(tmp_path / "block", config)
    evals = [r for r in trainer.run_dir.read_metrics() if r["kind"] == "eval"]
    assert [r["step"] for r in evals] == [600, 1200]
    assert trainer.run_dir.read_summary()["asked"] == 0


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"reward": "oracle"}, "unknown reward 'oracle'; accepted: learned, true, none"),
        ({"reward": "true", "backbone": "mrn"}, "backbone 'mrn' learns its reward"),
        ({"reward": "none", "teacher": "human"}, "teacher 'human' answers questions"),
    ],
)
def test_bad_baseline_settings_name_the_value_and_what_is_accepted(settings, message):
    with pytest.raises(ValueError, match=message):
        resolve_config("walker_walk", "small", settings)


def test_a_baseline_ignores_the_feedback_budget():
    config = resolve_config("walker_walk", "small", {"reward": "true", "steps": 2_000})
    assert config.steps == 2_000  # a learned-reward run this short would be refused
