"""The Python keywords of `PreferenceFeedback` and `make_config`, as a Python user passes
them: numpy's numbers taken where numbers are, booleans that are booleans, and a keyword
that only a human teacher reads refused without one."""

from __future__ import annotations

import json

import numpy as np
import pytest

import seqrank
from seqrank.errors import SettingError
from support.sb3_runs import feedback


def test_numpy_numbers_are_taken_where_numbers_are(tmp_path):
    taught = feedback(
        max_feedback=np.int64(40),
        reward_lr=np.float32(0.001),
        knn_k=np.int32(3),
        n_envs=np.int64(1),
    )
    assert taught.config.max_feedback == 40 and type(taught.config.max_feedback) is int
    assert type(taught.config.reward_lr) is float and taught.config.knn_k == 3
    assert taught.state.options["n_envs"] == 1 and type(taught.state.options["n_envs"]) is int
    taught.save(tmp_path / "saved")  # saved as JSON numbers
    saved = json.loads((tmp_path / "saved" / "settings.json").read_text())
    assert saved["config"]["max_feedback"] == 40 and saved["n_envs"] == 1
    config = seqrank.make_config("walker_walk", steps=np.int64(100_000), tau=np.float64(0.01))
    assert config.steps == 100_000 and type(config.steps) is int and type(config.tau) is float
    json.dumps(config.as_dict())


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"max_feedback": 40.0}, "max_feedback must be a whole number (an int), got 40.0 (float)"),
        ({"max_feedback": "40"}, "max_feedback must be a whole number (an int), got '40' (str)"),
        ({"max_feedback": True}, "max_feedback must be a whole number (an int), got True (bool)"),
        ({"reward_lr": "fast"}, "reward_lr must be a number, got 'fast' (str)"),
        ({"max_feedback": np.int64(0)}, "max_feedback must be a whole number from 1 to"),
    ],
)
def test_a_number_of_the_wrong_kind_is_named_with_its_type(settings, message):
    for make in (feedback, lambda **s: seqrank.make_config("walker_walk", **s)):
        with pytest.raises(SettingError) as refused:
            make(**settings)
        assert str(refused.value).startswith(message), str(refused.value)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"reset_critic": "no"}, "reset_critic must be True, False or None"),
        ({"pretrain": "yes"}, "pretrain must be True, False or None"),
        ({"pretrain": 1}, "pretrain must be True, False or None"),
        ({"wait_for_feedback": "false"}, "wait_for_feedback must be True or False"),
    ],
)
def test_booleans_must_be_booleans(options, message):
    with pytest.raises(SettingError, match=message) as refused:
        feedback(**options)
    assert repr(next(iter(options.values()))) in str(refused.value)


def test_booleans_of_numpy_and_none_are_taken():
    taught = feedback(pretrain=np.bool_(False), reset_critic=None, wait_for_feedback=True)
    assert (
        taught.state.options["pretrain"] is False and taught.state.options["reset_critic"] is None
    )


@pytest.mark.parametrize("options", [{"label_dir": "labels"}, {"page": object()}])
def test_keywords_of_the_labelling_page_are_refused_without_a_human_teacher(options, tmp_path):
    name = next(iter(options))
    with pytest.raises(SettingError, match=rf"^{name} is for teacher='human' only .*oracle"):
        feedback(**options)
    with pytest.raises(SettingError, match=rf"^{name} is for teacher='human' only"):
        feedback(**options, teacher=lambda first, second: seqrank.Answer.FIRST)
