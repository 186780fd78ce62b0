"""A run's config made and checked: `resolve_config(task, scale, overrides)` starts from the
suite defaults (SPEC section 2), applies the task's row of the paper's Table 2, then the
size preset, then the user's overrides, and `validate`s the result: every numeric setting in
the range it declares, and the rules settings keep together (`config.rules`).
"""

from __future__ import annotations

from dataclasses import fields, replace
from typing import Any

import seqrank.config.rules as rules
from seqrank.choices import RewardSignal, check_path
from seqrank.config.presets import BLOCK_SMALL_PRESET, SMALL_PRESET, table2_overrides
from seqrank.config.ranges import check_setting
from seqrank.config.roles import accepted_by
from seqrank.config.train_config import SCALES, TrainConfig
from seqrank.envs import canonical_task
from seqrank.errors import SettingError, setting
from seqrank.scale import scale_for_device


def resolve_config(task: str | None, scale: str, overrides: dict[str, Any]) -> TrainConfig:
    """Suite defaults, then Table 2, then the size preset, then what a replayed label file
    fixes (`rules.recorded_values`), then the user's overrides, which must agree
    with the file. `task` None: the label file's, else the default; `scale` auto: paper on
    CUDA, small elsewhere (`scale.resolve_scale`, on the device the overrides name)."""
    if scale == "auto":
        scale = scale_for_device(str(overrides.get("device", "auto")))
    elif scale not in SCALES:
        raise SettingError(f"unknown scale {scale!r}; accepted: auto, paper, small")
    recorded = rules.replayed(overrides.get("teacher"))
    taken = (
        {} if recorded is None else rules.recorded_values(recorded, overrides.get("max_feedback"))
    )
    given = {*overrides, "task"} if task is not None else set(overrides)
    task = task if task is not None else taken.get("task", TrainConfig.task)
    values = table2_overrides(task)
    if scale == "small":
        block = canonical_task(task)[0] == "block"
        values.update(BLOCK_SMALL_PRESET if block else SMALL_PRESET)
    values.update({**taken, "task": task, "scale": scale})
    values.update(overrides)
    config = replace(TrainConfig(), **values)
    if recorded is not None:
        rules.check_recorded(config, recorded, given)
    validate(config)
    return config


def config_differences(saved: TrainConfig, wanted: TrainConfig) -> list[str]:
    """The settings in which two configs differ, as `name saved -> wanted`."""
    return [
        f"{f.name} {getattr(saved, f.name)!s} -> {getattr(wanted, f.name)!s}"
        for f in fields(TrainConfig)
        if getattr(saved, f.name) != getattr(wanted, f.name)
    ]


def validate(config: TrainConfig) -> None:
    """Raise SettingError naming the bad value and what is accepted."""
    for f in fields(config):
        accepted = accepted_by(f)
        if accepted is not None:
            check_setting(f.name, accepted, getattr(config, f.name))
    suite = canonical_task(config.task)[0]
    if suite == "block" and config.backbone != "pebble":
        raise SettingError(
            f"{setting('backbone')} '{config.backbone}' needs SAC's actor; block:place learns "
            f"with DQN and supports {setting('backbone')} pebble"
        )
    check_path(config.path, config.precision, discrete=suite == "block")
    if not config.reward.asks:
        rules.check_baseline(config)
    elif config.teacher_spec.kind == "human" and not config.record_states:
        raise SettingError(
            f"{setting('teacher')} 'human' answers on the labelling page: use `seqrank label "
            f"online` (it also sets {setting('record_states')} 1, which the clips need)"
        )
    pretrains = config.reward is not RewardSignal.TRUE and config.unsup_steps > 0
    if pretrains and config.knn_k >= config.seed_steps:
        raise SettingError(
            f"{setting('knn_k')} {config.knn_k} must be smaller than {setting('seed_steps')} "
            f"{config.seed_steps}: pre-training measures each state's distance to its k-th "
            "nearest stored state"
        )
    if config.recheck_twice_gain < config.recheck_gain:
        raise SettingError(
            f"{setting('recheck_twice_gain')} {config.recheck_twice_gain} is below "
            f"{setting('recheck_gain')} {config.recheck_gain}: an answer is asked twice more "
            "only from a larger gain"
        )
    if config.reward_batch > config.max_feedback:
        raise SettingError(
            f"{setting('reward_batch')} {config.reward_batch} exceeds "
            f"{setting('max_feedback')} {config.max_feedback}: a session cannot ask more "
            "questions than the whole budget"
        )
    if config.reward.asks:
        rules.check_budget(config)
    rules.check_learner(config)
    rules.check_fine_tuning(config)
    rules.check_qpa(config)
    rules.check_segment_order(config)
    rules.check_crowd(config)
