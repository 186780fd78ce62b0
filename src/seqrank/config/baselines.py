"""The settings a baseline run never reads, by their roles: its results depend on the
others only, so a sweep plans it once whatever its variants do to these, and a report pools
baseline runs that differ in these alone."""

from __future__ import annotations

from seqrank.choices import RewardSignal
from seqrank.config.roles import Role
from seqrank.config.train_config import settings_of

# A baseline asks nothing, so it never reads what only asking reads. Its scheme and
# teacher are left to the layers that name methods by them (a sweep's axes, which plan a
# baseline without them; a report's method name).
ASKING_ONLY = settings_of(Role.FEEDBACK, Role.AGENT_FOR_FEEDBACK, Role.REWARD_TRAINING) - {
    "scheme",
    "teacher",
}
# what the true-reward agent lacks beyond the questions: pre-training, the critic reset
# after it, and a reward model
PRETRAINING = settings_of(Role.PRETRAINING)
REWARD_MODEL_SIZES = settings_of(Role.REWARD_MODEL)


def unread_settings(reward: RewardSignal, start_from: bool = False) -> frozenset[str]:
    """The settings a run that learns from `reward` never reads (none for a learned
    reward; the no-feedback run's untrained model is fit to nothing); `start_from`: the
    run's own (a run started from a saved one checks the saved reward model's sizes
    against its own)."""
    if reward is RewardSignal.TRUE:
        sizes = frozenset() if start_from else REWARD_MODEL_SIZES
        return ASKING_ONLY | PRETRAINING | sizes
    if reward is RewardSignal.NONE:
        return ASKING_ONLY
    return frozenset()
