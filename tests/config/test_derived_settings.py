"""The lists of settings derived from each setting's declared role and range equal the
lists that were written by hand before (issue 48): the derivation changed nothing. A setting
added since is left out of the comparison (its role places it); one of these that changes
role fails here."""

from __future__ import annotations

from dataclasses import fields

import pytest

from seqrank.choices import RewardSignal
from seqrank.config import TrainConfig, unread_settings
from seqrank.config.ranges import MAX_COUNT, Count, Number
from seqrank.config.roles import accepted_by
from seqrank.reference import REFERENCE_KEY
from seqrank.sb3.settings import FEEDBACK_SETTINGS
from seqrank.sb3.settings import REFUSED_SETTINGS as SB3_REFUSED

# the settings there were when the lists were written by hand
HAND_SETTINGS = {
    *("task", "scheme", "teacher", "reward", "backbone", "seed", "steps", "device", "scale"),
    *("path", "precision", "hidden", "layers", "batch", "actor_lr", "critic_lr", "alpha_lr"),
    *("init_temperature", "discount", "tau", "target_update_every", "seed_steps"),
    *("unsup_steps", "knn_k", "updates_after_reset", "max_feedback", "reward_batch"),
    *("feedback_frequency", "segment_length", "augment", "recheck_gain"),
    *("recheck_twice_gain", "path_unchecked", "selection", "oversample", "episodes_kept"),
    *("query_episodes", "hybrid_replay", "hybrid_episodes", "overlap", "crowd_weighting"),
    *("annotators", "record_states", "start_from", "parts", "reward_ensemble"),
    *("reward_hidden", "reward_layers", "reward_lr", "reward_minibatch", "reward_epochs"),
    *("reward_stop_accuracy", "reward_stop_on", "reward_learner", "surf_threshold"),
    *("surf_unlabelled_ratio", "surf_unlabelled_batch", "surf_loss_weight", "surf_crop"),
    *("rime_alpha", "rime_beta_max", "rime_beta_min", "rime_decay_updates"),
    *("rime_tau_upper", "rime_min_epochs", "warm_start", "meta_update_frequency"),
    *("meta_loss_weight", "eval_every", "eval_episodes", "checkpoint_every", "heldout_pairs"),
}
# as written by hand in sb3/settings.py, reference.py, config.py and config_ranges.py
HAND_SB3_REFUSED = {
    "task",
    "reward",
    "backbone",
    "path",
    "precision",
    "hidden",
    "layers",
    "batch",
    "actor_lr",
    "critic_lr",
    "alpha_lr",
    "init_temperature",
    "discount",
    "tau",
    "target_update_every",
    "hybrid_replay",
    "hybrid_episodes",
    "start_from",
    "parts",
    "warm_start",
    "meta_update_frequency",
    "meta_loss_weight",
    "eval_every",
    "eval_episodes",
    "checkpoint_every",
}
HAND_REFERENCE_KEY = (
    "scale",
    "hidden",
    "layers",
    "batch",
    "actor_lr",
    "critic_lr",
    "alpha_lr",
    "init_temperature",
    "discount",
    "tau",
    "target_update_every",
    "seed_steps",
)
HAND_ASKING_ONLY = {
    "selection",
    "record_states",
    "heldout_pairs",
    "parts",
    "oversample",
    "max_feedback",
    "reward_batch",
    "feedback_frequency",
    "segment_length",
    "episodes_kept",
    "query_episodes",
    "hybrid_replay",
    "hybrid_episodes",
    "overlap",
    "crowd_weighting",
    "annotators",
    "meta_update_frequency",
    "meta_loss_weight",
    "augment",
    "recheck_gain",
    "recheck_twice_gain",
    "path_unchecked",
    "reward_learner",
    "surf_threshold",
    "surf_unlabelled_ratio",
    "surf_unlabelled_batch",
    "surf_loss_weight",
    "surf_crop",
    "rime_alpha",
    "rime_beta_max",
    "rime_beta_min",
    "rime_decay_updates",
    "rime_tau_upper",
    "rime_min_epochs",
}
HAND_REWARD_FITTING = {
    "reward_minibatch",
    "reward_epochs",
    "reward_stop_accuracy",
    "reward_stop_on",
}
HAND_PRETRAINING_AND_REWARD_MODEL = HAND_REWARD_FITTING | {
    "unsup_steps",
    "knn_k",
    "updates_after_reset",
    "warm_start",
    "reward_ensemble",
    "reward_hidden",
    "reward_layers",
    "reward_lr",
}
HAND_REWARD_MODEL_SIZES = {"reward_ensemble", "reward_hidden", "reward_layers"}
HAND_UNREAD = {
    (RewardSignal.TRUE, False): HAND_ASKING_ONLY | HAND_PRETRAINING_AND_REWARD_MODEL,
    (RewardSignal.TRUE, True): (HAND_ASKING_ONLY | HAND_PRETRAINING_AND_REWARD_MODEL)
    - HAND_REWARD_MODEL_SIZES,
    (RewardSignal.NONE, False): HAND_ASKING_ONLY
    | HAND_REWARD_FITTING
    | {"warm_start", "reward_lr"},
    (RewardSignal.NONE, True): HAND_ASKING_ONLY | HAND_REWARD_FITTING | {"warm_start", "reward_lr"},
    (RewardSignal.LEARNED, False): set(),
    (RewardSignal.LEARNED, True): set(),
}
HAND_MAX = {
    "seed": 2**32 - 1,
    "record_states": 1,
    "oversample": 100,
    "heldout_pairs": 100_000,
    "surf_unlabelled_ratio": 1_000,
    "surf_unlabelled_batch": 100,
    "warm_start": 1,
}
HAND_FROM_ZERO = {
    "seed",
    "seed_steps",
    "unsup_steps",
    "updates_after_reset",
    "record_states",
    "path_unchecked",
    "query_episodes",
    "hybrid_replay",
    "surf_crop",
    "warm_start",
    "overlap",
}
HAND_AT_MOST_ONE = {
    "overlap",
    "discount",
    "tau",
    "reward_stop_accuracy",
    "hybrid_replay",
    "surf_threshold",
    "rime_tau_upper",
}


def known(names):
    return {name for name in names if name in HAND_SETTINGS}


def test_every_setting_of_then_is_still_a_setting():
    assert {f.name for f in fields(TrainConfig)} >= HAND_SETTINGS


def test_the_sb3_layer_refuses_the_settings_it_refused_by_hand():
    assert known(SB3_REFUSED) == HAND_SB3_REFUSED
    assert known(FEEDBACK_SETTINGS) == HAND_SETTINGS - HAND_SB3_REFUSED - {"scale"}


def test_the_reference_is_keyed_by_the_settings_it_was_keyed_by():
    in_key = tuple(name for name in REFERENCE_KEY if name in HAND_SETTINGS)
    assert in_key == HAND_REFERENCE_KEY  # in the same order: the file's entries are written so


@pytest.mark.parametrize(("reward", "start_from"), sorted(HAND_UNREAD, key=str))
def test_a_baseline_leaves_unread_what_it_left_unread(reward, start_from):
    assert known(unread_settings(reward, start_from)) == HAND_UNREAD[(reward, start_from)]


def test_each_numeric_setting_accepts_what_it_accepted():
    ranges = {f.name: accepted_by(f) for f in fields(TrainConfig) if f.name in HAND_SETTINGS}
    counts = {name: r for name, r in ranges.items() if isinstance(r, Count)}
    numbers = {name: r for name, r in ranges.items() if isinstance(r, Number)}
    assert {name: r.high for name, r in counts.items() if r.high != MAX_COUNT} == HAND_MAX
    from_zero = {name for name, r in counts.items() if r.low == 0}
    from_zero |= {name for name, r in numbers.items() if r.from_zero}
    assert from_zero == HAND_FROM_ZERO
    assert {name for name, r in counts.items() if r.low not in (0, 1)} == set()
    assert {name for name, r in numbers.items() if r.at_most_one} == HAND_AT_MOST_ONE
