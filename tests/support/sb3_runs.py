"""Tiny SB3 runs from preferences on the line task (`support.sb3_envs`)."""

from __future__ import annotations

import copy
from typing import Any

from seqrank.sb3 import PreferenceFeedback, PreferenceReplayBuffer

LINE = "support.sb3_envs:make_line"
TINY = dict(
    max_feedback=40,
    reward_batch=10,
    feedback_frequency=400,
    seed_steps=100,
    unsup_steps=400,
    segment_length=10,
    steps=3000,
    reward_epochs=5,
    heldout_pairs=50,
    device="cpu",
)
SMALL_SAC = dict(
    policy_kwargs=dict(net_arch=[32, 32]),
    batch_size=64,
    learning_starts=100,
    replay_buffer_class=PreferenceReplayBuffer,  # pre-training's state-entropy reward
)


def small_sac() -> dict[str, Any]:
    """A copy of SMALL_SAC: SB3's SAC writes `use_sde` into the policy_kwargs it is given,
    which TD3 then refuses."""
    return copy.deepcopy(SMALL_SAC)


def feedback(task: str = LINE, **settings: Any) -> PreferenceFeedback:
    return PreferenceFeedback(task, **{**TINY, **settings})
