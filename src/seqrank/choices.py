"""The run's named choices as types, each checked once when a config is made.

They are `StrEnum`s: a member equals its name as a string, so the saved config.json, the
CLI and the sweep files keep using plain strings.
"""

from __future__ import annotations

from enum import StrEnum

from seqrank.errors import SettingError, setting
from seqrank.errors import parse_choice as parse_choice  # defined with the error it raises


class Backbone(StrEnum):
    PEBBLE = "pebble"
    MRN = "mrn"


class Scale(StrEnum):
    PAPER = "paper"  # Table 2 sizes
    SMALL = "small"  # a 2-core CPU preset


class Device(StrEnum):
    AUTO = "auto"  # CUDA when there is one
    CPU = "cpu"
    CUDA = "cuda"


class TrainingPath(StrEnum):
    AUTO = "auto"  # fast on CUDA for SAC tasks, reference elsewhere
    REFERENCE = "reference"
    FAST = "fast"


class Precision(StrEnum):
    AUTO = "auto"  # TF32 for the fast path on CUDA, fp32 elsewhere
    FP32 = "fp32"
    TF32 = "tf32"
    BF16 = "bf16"


class CrowdWeighting(StrEnum):
    """How a crowd's labels count in reward training (`seqrank.feedback.reliability`)."""

    RELIABILITY = "reliability"  # each label the probability that its annotator is right
    NONE = "none"  # every answer as given
    DROP = "drop"  # a flagged annotator's labels left out (results/crowd/, issue 49)
    # as drop, and each question of a member flagged before a session asked again of one
    # who is not, in place of the overlap's opinions on it (`feedback.overlap.reasked`,
    # `SessionRequest.distrusted`; issue 49, item 3)
    REASK = "reask"
    # a flagged annotator's labels trained as the probability that they are right (left out
    # when their estimate is 1/2 or less); everybody else's as given
    SOFTEN = "soften"


class StopOn(StrEnum):
    """Which labels a session's reward training counts for its early stop
    (`reward_stop_accuracy`)."""

    ALL = "all"  # every label, asked and inferred: PEBBLE's rule, as the paper trains
    ASKED = "asked"  # the asked pairs only: easy inferred pairs cannot end a fit at once


class RewardSignal(StrEnum):
    """What the agent learns from."""

    LEARNED = "learned"  # a reward model trained on preferences (the method)
    TRUE = "true"  # the environment's reward, no feedback: the true-reward baseline
    NONE = "none"  # no feedback: pre-training, then the untrained reward model (the floor)

    @property
    def asks(self) -> bool:
        return self is RewardSignal.LEARNED

    @property
    def method(self) -> str:
        """The name a report gives a baseline run."""
        return {"learned": "learned", "true": "true-reward", "none": "no-feedback"}[self.value]


class Augment(StrEnum):
    FULL = "full"  # the paper's closure: every answer is trusted and chained
    CHECKED = "checked"  # noise-aware: re-check big moves, chain few unconfirmed answers


class RewardLearner(StrEnum):
    """How the reward ensemble learns from the labelled pairs (docs/concepts/reward-learners.md)."""

    PLAIN = "plain"  # Bradley-Terry on every labelled pair (PEBBLE)
    SURF = "surf"  # + confident pseudo-labels on unlabelled pairs, temporal cropping
    RIME = "rime"  # trusted labels by their loss, the least likely ones flipped


class Selection(StrEnum):
    UNIFORM = "uniform"
    DISAGREEMENT = "disagreement"
    ENTROPY = "entropy"


class SegmentOrder(StrEnum):
    """The order a session's new segments reach its scheme (issue 46)."""

    UNIFORM = "uniform"  # as drawn: a uniform episode, a uniform start (PEBBLE's sampling)
    # the same segments in the order they were collected: later, better segments challenge
    # an early root (the paper's section D.6 counts suggest its stream came so)
    COLLECTION = "collection"


def check_path(path: str, precision: str, discrete: bool) -> None:
    """A SettingError for a path and precision that do not go together (whatever the
    device)."""
    if discrete and path == TrainingPath.FAST:
        raise SettingError(
            f"{setting('path')} 'fast' is SAC's fast update; block:place learns with DQN: use "
            f"{setting('path')} reference or auto"
        )
    if path == TrainingPath.REFERENCE and precision not in (Precision.AUTO, Precision.FP32):
        raise fast_path_needed(precision, discrete)


def fast_path_needed(precision: str, discrete: bool) -> SettingError:
    """The error for a precision other than fp32 on the reference path (chosen, or what
    `--path auto` resolved to); a discrete task (DQN) has no fast path to offer."""
    way_out = (
        f"{setting('precision')} fp32"
        if discrete
        else f"{setting('path')} fast, or {setting('precision')} fp32"
    )
    return SettingError(
        f"{setting('precision')} '{precision}' needs the fast path: the reference path is "
        f"strict fp32 (use {way_out})"
    )
