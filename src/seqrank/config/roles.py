"""What part of a run each setting configures, declared once with the setting.

Every `TrainConfig` field is made by `declare(role, default, accepted)`: its role and,
for a number, the values it accepts (`config.ranges`). The lists that treat settings
alike are derived from the roles, never written out: what `PreferenceFeedback` refuses
(`sb3.settings`), what a baseline never reads (`config.baselines`), what keys the
true-reward reference (`reference`). `check_declared` refuses a field without a role, so a
new setting cannot be left out of them.
"""

from __future__ import annotations

from dataclasses import Field, field, fields
from enum import StrEnum
from typing import Any

from seqrank.config.ranges import Accepted, Count, Number

ROLE = "seqrank.role"
ACCEPTED = "seqrank.accepted"


class Role(StrEnum):
    """What a setting configures, and so which runs and layers read it."""

    # what the run is and where it runs: every run reads these; with Stable-Baselines3
    # the task is the SB3 model's environment and the reward always the learned one
    RUN = "run"
    # how long the run lasts and its random warm-up: every run
    SCHEDULE = "schedule"
    # PEBBLE's unsupervised pre-training and the critic reset that ends it: runs with a
    # reward model (not the true-reward agent)
    PRETRAINING = "pretraining"
    # seqrank's own agent and how its update computes: every run of seqrank's loop; the
    # SB3 model replaces it
    AGENT = "agent"
    # what seqrank's agent does for learning from feedback (QPA's hybrid replay, MRN's
    # meta update, the study's fresh episodes per part): only where questions are asked,
    # and the SB3 model replaces it
    AGENT_FOR_FEEDBACK = "agent for feedback"
    # the sessions: who answers what, how often, on which segments, what an answer
    # implies: only where questions are asked
    FEEDBACK = "feedback"
    # the reward model's sizes: runs with a reward model (the no-feedback run's is untrained)
    REWARD_MODEL = "reward model"
    # how the reward model learns from labels, and how well it did on held-out pairs:
    # only where questions are asked
    REWARD_TRAINING = "reward training"
    # seqrank's loop's own evaluation, checkpoints and the saved run it starts from:
    # every run of seqrank's loop; SB3 has its own callbacks and savers
    BOOKKEEPING = "bookkeeping"


def declare(role: Role, default: Any, accepted: Accepted | None = None) -> Any:
    """A `TrainConfig` field: its default, its role and, for an int or float setting,
    the values it accepts."""
    return field(default=default, metadata={ROLE: role, ACCEPTED: accepted})


def role_of(setting: Field[Any]) -> Role:
    return Role(setting.metadata[ROLE])


def accepted_by(setting: Field[Any]) -> Accepted | None:
    """The values a numeric setting accepts (None for the others)."""
    accepted: Accepted | None = setting.metadata.get(ACCEPTED)
    return accepted


# which range goes with which annotation (annotations are strings: `from __future__`)
RANGE_KINDS: dict[str, type[Count] | type[Number]] = {"int": Count, "float": Number}


def check_declared(config_type: type[Any]) -> None:
    """TypeError naming each field of the dataclass `config_type` made without `declare`
    (no role: no list would know it), and each int or float without its range (or a range
    of the other kind, or on a setting that is no number)."""
    problems = []
    for setting in fields(config_type):
        if not isinstance(setting.metadata.get(ROLE), Role):
            problems.append(f"{setting.name} has no role")
            continue
        kind = RANGE_KINDS.get(str(setting.type))
        accepted = accepted_by(setting)
        if kind is None and accepted is not None:
            problems.append(f"{setting.name} ({setting.type}) has a range but is no number")
        elif kind is not None and not isinstance(accepted, kind):
            problems.append(f"{setting.name} ({setting.type}) needs a {kind.__name__} range")
    if problems:
        raise TypeError(
            f"{config_type.__name__}: {'; '.join(problems)}: declare each setting with "
            "config.roles.declare(Role..., default, accepted)"
        )
