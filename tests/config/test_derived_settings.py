"""The lists of settings derived from each setting's declared role and range equal the
lists that were written by hand before (issue 48): the derivation changes nothing."""

from __future__ import annotations

import pytest

from seqrank.choices import RewardSignal
from seqrank.config import unread_settings
from seqrank.config_ranges import AT_MOST_ONE, FROM_ZERO, MAX
from seqrank.reference import AGENT_SETTINGS as REFERENCE_KEY
from seqrank.sb3.settings import AGENT_SETTINGS as SB3_REFUSED
from seqrank.sb3.settings import FEEDBACK_SETTINGS

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


def test_the_sb3_layer_refuses_the_settings_it_refused_by_hand():
    assert set(SB3_REFUSED) == HAND_SB3_REFUSED
    assert set(FEEDBACK_SETTINGS).isdisjoint(HAND_SB3_REFUSED | {"scale"})


def test_the_reference_is_keyed_by_the_settings_it_was_keyed_by():
    assert tuple(REFERENCE_KEY) == HAND_REFERENCE_KEY  # the shipped file's entries: same order


@pytest.mark.parametrize(("reward", "start_from"), sorted(HAND_UNREAD, key=str))
def test_a_baseline_leaves_unread_what_it_left_unread(reward, start_from):
    assert unread_settings(reward, start_from) == HAND_UNREAD[(reward, start_from)]


def test_the_ranges_are_todays():
    assert dict(MAX) == HAND_MAX
    assert set(FROM_ZERO) == HAND_FROM_ZERO
    assert set(AT_MOST_ONE) == HAND_AT_MOST_ONE
