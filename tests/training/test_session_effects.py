"""What a feedback session does to the agent, pinned on the reference path in a real run:
the critic reset once, at the first session, and every stored transition relabelled.

The steps are worked out by hand from `tiny_config`: a warm-up of 300 steps, 900 steps of
pre-training, so the first session comes at step 1 200; with 30 questions in sessions of
10 every 500 steps, the others at 1 700 and 2 200.
"""

from __future__ import annotations

import pytest
import torch

from seqrank.agents.sac.critics import canonical_weights
from seqrank.training import loop
from seqrank.training.runs import RunDir
from seqrank.training.trainer import Trainer
from support.runs import tiny_config

FIRST_SESSION, SESSIONS = 1200, (1200, 1700, 2200)


def trainer_watching_resets(tmp_path, monkeypatch, **overrides):
    """A reference-path trainer whose critic resets are recorded: (step, updates), and
    whether the reset gave the critic new weights and a fresh optimiser."""
    config = tiny_config(path="reference", **overrides)
    trainer = Trainer(config, RunDir.create(tmp_path / "run", config, "cpu"))
    resets: list[tuple[int, int, bool, set[int]]] = []
    real_reset = loop.reset_critic

    def watched(agent, replay, updates, batch, generator):
        before = canonical_weights(agent.critic)
        real_reset(agent, replay, updates, batch, generator)
        after = canonical_weights(agent.critic)
        moved = all(not torch.equal(before[k], after[k]) for k in before)
        steps = {int(s["step"]) for s in agent.critic_opt.state.values()}
        resets.append((trainer.counters.step, updates, moved, steps))

    monkeypatch.setattr(loop, "reset_critic", watched)
    return trainer, resets


@pytest.mark.parametrize("reward", ["learned", "none"])
def test_the_critic_is_reset_once_at_the_first_session(tmp_path, monkeypatch, reward):
    trainer, resets = trainer_watching_resets(
        tmp_path, monkeypatch, reward=reward, updates_after_reset=7
    )
    trainer.train()
    # one reset, where the first session is (the no-feedback run resets there too); its
    # critic is new and its Adam state counts only the 7 head-start updates
    assert resets == [(FIRST_SESSION, 7, True, {7})]


def test_after_every_session_the_whole_buffer_carries_the_new_models_reward(tmp_path, monkeypatch):
    config = tiny_config(path="reference")
    trainer = Trainer(config, RunDir.create(tmp_path / "run", config, "cpu"))
    seen: list[tuple[int, float]] = []
    learn_from_session = loop._learn_from_session

    def checked(t, answered):
        learn_from_session(t, answered)
        replay, model = t.replay, t.reward.model
        n = len(replay)
        with torch.no_grad():
            expected = model.reward(replay.obs[:n], replay.action[:n])
        seen.append((t.counters.step, float((replay.reward[:n] - expected).abs().max())))

    monkeypatch.setattr(loop, "_learn_from_session", checked)
    trainer.train()
    assert [step for step, _ in seen] == list(SESSIONS)
    # the transitions stored before each session were rewarded by an older model (or,
    # before the first, not at all); each must now hold the new model's reward
    assert all(gap < 1e-5 for _, gap in seen), seen
