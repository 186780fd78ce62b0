"""`feedback.reward(observations, actions)` checks its batch before and after the first
session: a batch of the wrong shape is refused with the expected and received shapes,
never broadcast into a wrong number or failing inside numpy or torch."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from seqrank.sb3 import PreferenceFeedback
from support.sb3_envs import make_wide_line
from support.sb3_runs import TINY, feedback

EXPECTED = r"reward\(\) takes a batch: observations \(N, 2\) and actions \(N, 3\); got "


@pytest.mark.parametrize(
    ("obs_shape", "action_shape", "received"),
    [
        ((4, 2), (4,), r"observations \(4, 2\) and actions \(4,\)"),  # not broadcast to 3
        ((4, 5), (4, 3), r"observations \(4, 5\) and actions \(4, 3\)"),
        ((4, 2), (4, 2), r"observations \(4, 2\) and actions \(4, 2\)"),
        ((2,), (3,), r"observations \(2,\) and actions \(3,\)"),
        ((4, 2), (3, 3), r"observations \(4, 2\) and actions \(3, 3\)"),
    ],
)
def test_a_batch_of_the_wrong_shape_is_refused_with_both_shapes(obs_shape, action_shape, received):
    taught = PreferenceFeedback(make_wide_line(), **TINY)
    with pytest.raises(ValueError, match=EXPECTED + received + "$") as refused:
        taught.reward(np.zeros(obs_shape), np.zeros(action_shape))
    assert "\n" not in str(refused.value)


def test_a_batch_of_the_right_shape_gets_a_reward_each():
    taught = PreferenceFeedback(make_wide_line(), **TINY)
    assert taught.reward(np.zeros((4, 2)), np.zeros((4, 3))).shape == (4,)
    line = feedback()  # a one-number action: (N,) or (N, 1)
    assert line.reward(np.zeros((4, 2)), np.zeros(4)).tolist() == [0.0] * 4
    assert line.reward(np.zeros((4, 2)), np.zeros((4, 1))).shape == (4,)


def test_discrete_actions_are_indices_of_the_space():
    taught = PreferenceFeedback(gym.make("CartPole-v1"), **{**TINY, "unsup_steps": 0})
    assert taught.reward(np.zeros((2, 4)), np.array([0, 1])).shape == (2,)
    assert taught.reward(np.zeros((2, 4)), np.array([[1], [0]])).shape == (2,)
    expected = r"observations \(N, 4\) and actions \(N,\), indices from 0 to 1; got "
    for bad, named in [
        (np.array([0, 2]), r"actions \[0 2\]"),
        (np.array([0.5, 1.0]), r"actions \[0\.5 1\. \]"),
        (np.zeros((2, 2)), r"actions \(2, 2\)"),
    ]:
        with pytest.raises(ValueError, match=expected + r".*" + named):
            taught.reward(np.zeros((2, 4)), bad)
