"""One frozen config per run: the CLI options, the saved config.json and the presets at once.

`resolve_config(task, scale, overrides)` starts from the suite defaults (SPEC section 2),
applies the task's row of the paper's Table 2, then the size preset, then the user's
overrides. Every field is a `seqrank train` option (`--field-name VALUE`).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

from seqrank.choices import (
    Backbone,
    Device,
    Precision,
    RewardLearner,
    RewardSignal,
    Scale,
    Selection,
    TrainingPath,
    check_path,
    parse_choice,
)
from seqrank.envs import canonical_task
from seqrank.feedback.schemes import SchemeName
from seqrank.feedback.teachers import TeacherSpec, parse_teacher
from seqrank.presets import BLOCK_SMALL_PRESET, SMALL_PRESET, table2_overrides
from seqrank.reward.rime import RimeSettings
from seqrank.reward.surf import SurfSettings

BACKBONES = tuple(Backbone)
SELECTIONS = tuple(Selection)
SCALES = tuple(Scale)
DEVICES = tuple(Device)
PATHS = tuple(TrainingPath)
PRECISIONS = tuple(Precision)
# the choices of a run, checked and turned into their types when a config is made
CHOICES: dict[str, type[Any]] = {
    "scheme": SchemeName,
    "backbone": Backbone,
    "selection": Selection,
    "scale": Scale,
    "device": Device,
    "path": TrainingPath,
    "precision": Precision,
    "reward": RewardSignal,
    "reward_learner": RewardLearner,
}


@dataclass(frozen=True)
class TrainConfig:
    task: str = "walker_walk"
    scheme: SchemeName = SchemeName.SEQUENTIAL
    teacher: str = "oracle"  # a `parse_teacher` value: preset[,knob=value...], replay:FILE, human
    reward: RewardSignal = RewardSignal.LEARNED  # `true` and `none` are the baselines
    backbone: Backbone = Backbone.PEBBLE
    seed: int = 0
    steps: int = 500_000
    device: Device = Device.AUTO
    scale: Scale = Scale.PAPER
    path: TrainingPath = TrainingPath.AUTO
    precision: Precision = Precision.AUTO
    # SAC (SPEC section 2)
    hidden: int = 1024
    layers: int = 2
    batch: int = 1024
    actor_lr: float = 5e-4
    critic_lr: float = 5e-4
    alpha_lr: float = 1e-4
    init_temperature: float = 0.1
    discount: float = 0.99
    tau: float = 0.005
    target_update_every: int = 2
    # schedule (SPEC section 1)
    seed_steps: int = 1_000
    unsup_steps: int = 9_000
    knn_k: int = 5
    updates_after_reset: int = 100
    # feedback (SPEC sections 3 and 8)
    max_feedback: int = 400
    reward_batch: int = 40
    feedback_frequency: int = 20_000
    segment_length: int = 50
    selection: Selection = Selection.UNIFORM
    oversample: int = 10
    episodes_kept: int = 100
    record_states: int = 0  # 1: keep physics states so labelled segments can be re-rendered
    # fine-tuning (the user study's first kind): a saved run's agent, reward model, replay
    # buffer and episodes to start from, and what the sessions' clips show (`FINETUNE_PARTS`)
    start_from: str = ""
    parts: str = ""
    # reward model (SPEC section 5)
    reward_ensemble: int = 3
    reward_hidden: int = 256
    reward_layers: int = 3
    reward_lr: float = 3e-4
    reward_minibatch: int = 128
    reward_epochs: int = 50
    reward_stop_accuracy: float = 0.97
    # reward learners beyond the paper (SURF, RIME): docs/reward-learners.md; the defaults
    # and their sources are in `SurfSettings` and `RimeSettings`
    reward_learner: RewardLearner = RewardLearner.PLAIN
    surf_threshold: float = SurfSettings.threshold
    surf_unlabelled_ratio: int = SurfSettings.unlabelled_ratio
    surf_unlabelled_batch: int = SurfSettings.unlabelled_batch
    surf_loss_weight: float = SurfSettings.loss_weight
    surf_crop: int = SurfSettings.crop
    rime_alpha: float = RimeSettings.alpha
    rime_beta_max: float = RimeSettings.beta_max
    rime_beta_min: float = RimeSettings.beta_min
    rime_decay_updates: int = RimeSettings.decay_updates
    rime_tau_upper: float = RimeSettings.tau_upper
    warm_start: int = 0  # 1: RIME's warm start of the reward model in pre-training
    # MRN (SPEC section 7)
    meta_update_frequency: int = 1_000
    meta_loss_weight: float = 0.1
    # evaluation, logging, checkpoints
    eval_every: int = 10_000
    eval_episodes: int = 10
    checkpoint_every: int = 10_000
    heldout_pairs: int = 500

    def __post_init__(self) -> None:
        for name, kind in CHOICES.items():
            object.__setattr__(self, name, parse_choice(kind, getattr(self, name), name))
        parse_teacher(self.teacher)

    @property
    def teacher_spec(self) -> TeacherSpec:
        return parse_teacher(self.teacher)

    @property
    def sessions(self) -> int:
        return math.ceil(self.max_feedback / self.reward_batch)

    @property
    def first_session_step(self) -> int:
        return self.seed_steps + self.unsup_steps

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def resolve_config(task: str, scale: str, overrides: dict[str, Any]) -> TrainConfig:
    """Suite defaults, then Table 2, then the size preset, then the user's overrides."""
    values = table2_overrides(task)
    if scale == "small":
        block = canonical_task(task)[0] == "block"
        values.update(BLOCK_SMALL_PRESET if block else SMALL_PRESET)
    values["scale"] = scale
    values.update(overrides)
    config = replace(TrainConfig(), **values)
    validate(config)
    return config


# The numeric settings' ranges: whole numbers from 1 (from 0 for these) to MAX_COUNT,
# numbers finite and > 0 (and at most 1 for these); the seed is what numpy, torch and the
# simulators accept.
MAX_COUNT = 2**31 - 1
MAX_SEED = 2**32 - 1
# settings whose size each feedback session allocates at once: a candidate pool this many
# times what the scheme needs, and this many held-out segment pairs
MAX = {
    "seed": MAX_SEED,
    "record_states": 1,
    "oversample": 100,
    "heldout_pairs": 100_000,
    "surf_unlabelled_ratio": 1_000,  # unlabelled pairs per question, cut each session
    "surf_unlabelled_batch": 100,
    "warm_start": 1,
}
FROM_ZERO = (
    "seed",
    "seed_steps",
    "unsup_steps",
    "updates_after_reset",
    "record_states",
    "surf_crop",
    "warm_start",
)
AT_MOST_ONE = ("discount", "tau", "reward_stop_accuracy", "surf_threshold", "rime_tau_upper")


def check_setting(name: str, value: Any) -> None:
    """ValueError unless the numeric setting `name` holds a value in its range."""
    kind = str(next(f.type for f in fields(TrainConfig) if f.name == name))
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{name} must be a whole number, got {value!r}")
        low = 0 if name in FROM_ZERO else 1
        high = MAX.get(name, MAX_COUNT)
        if not low <= value <= high:
            raise ValueError(f"{name} must be a whole number from {low} to {high}, got {value}")
        return
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{name} must be a number, got {value!r}")
    unit = name in AT_MOST_ONE
    if not math.isfinite(value) or value <= 0 or (unit and value > 1):
        accepted = "a number in (0, 1]" if unit else "a finite number > 0"
        raise ValueError(f"{name} must be {accepted}, got {value}")


def config_differences(saved: TrainConfig, wanted: TrainConfig) -> list[str]:
    """The settings in which two configs differ, as `name saved -> wanted`."""
    return [
        f"{f.name} {getattr(saved, f.name)!s} -> {getattr(wanted, f.name)!s}"
        for f in fields(TrainConfig)
        if getattr(saved, f.name) != getattr(wanted, f.name)
    ]


def validate(config: TrainConfig) -> None:
    """Raise ValueError naming the bad value and what is accepted."""
    for f in fields(config):
        if f.type in ("int", "float"):
            check_setting(f.name, getattr(config, f.name))
    suite = canonical_task(config.task)[0]
    if suite == "block" and config.backbone != "pebble":
        raise ValueError(
            f"backbone '{config.backbone}' needs SAC's actor; block:place learns with DQN "
            "and supports backbone pebble"
        )
    check_path(config.path, config.precision, discrete=suite == "block")
    if not config.reward.asks:
        _check_baseline(config)
    elif config.teacher_spec.kind == "human" and not config.record_states:
        raise ValueError(
            "teacher 'human' answers on the labelling page: use `seqrank label online` "
            "(it also sets record_states 1, which the clips need)"
        )
    pretrains = config.reward is not RewardSignal.TRUE and config.unsup_steps > 0
    if pretrains and config.knn_k >= config.seed_steps:
        raise ValueError(
            f"knn_k {config.knn_k} must be smaller than seed_steps {config.seed_steps}: "
            "pre-training measures each state's distance to its k-th nearest stored state"
        )
    if config.reward_batch > config.max_feedback:
        raise ValueError(
            f"reward_batch {config.reward_batch} exceeds max_feedback {config.max_feedback}: "
            "a session cannot ask more questions than the whole budget"
        )
    if config.reward.asks:
        _check_budget(config)
    _check_learner(config)
    _check_fine_tuning(config)


def _check_learner(config: TrainConfig) -> None:
    """The reward learners' settings that depend on each other."""
    if config.surf_crop >= config.segment_length:
        raise ValueError(
            f"surf_crop {config.surf_crop} must be smaller than segment_length "
            f"{config.segment_length}: a crop keeps at least one step; accepted: 0 to "
            f"{config.segment_length - 1}"
        )
    if config.rime_beta_min > config.rime_beta_max:
        raise ValueError(
            f"rime_beta_min {config.rime_beta_min} exceeds rime_beta_max "
            f"{config.rime_beta_max}: the uncertainty weight decays from max to min"
        )
    if config.rime_tau_upper >= 0.5:
        raise ValueError(
            f"rime_tau_upper must be below 0.5, got {config.rime_tau_upper}: RIME flips a "
            "label the model gives less than this probability"
        )


# what the clips of a session show, in session order (the study's instructions: first
# low-performing trajectories, then trajectories of varying performance)
FINETUNE_PARTS = ("low", "varied")


def _check_fine_tuning(config: TrainConfig) -> None:
    parts = [p for p in config.parts.split(",") if p]
    if any(p not in FINETUNE_PARTS for p in parts):
        raise ValueError(
            f"parts {config.parts!r}: give a comma-separated list of {', '.join(FINETUNE_PARTS)}"
        )
    if not config.start_from:
        return
    source = Path(config.start_from)
    if not (source / "checkpoint.pt").is_file() or not (source / "config.json").is_file():
        raise ValueError(
            f"start_from {config.start_from!r}: not a run directory with a checkpoint "
            "(config.json and checkpoint.pt)"
        )
    saved = json.loads((source / "config.json").read_text())
    if canonical_task(saved["task"]) != canonical_task(config.task):
        raise ValueError(
            f"start_from {config.start_from!r} trained {saved['task']!r}, not {config.task!r}"
        )
    for name in ("hidden", "layers", "reward_hidden", "reward_layers", "reward_ensemble"):
        if saved.get(name) != getattr(config, name):
            raise ValueError(
                f"start_from {config.start_from!r} has {name} {saved.get(name)!r}, this run "
                f"{getattr(config, name)!r}: a run starts from one of the same task and sizes"
            )


def _check_budget(config: TrainConfig) -> None:
    """Every session of the feedback budget falls within the run's steps."""
    last_session = config.first_session_step + (config.sessions - 1) * config.feedback_frequency
    if last_session >= config.steps:
        raise ValueError(
            f"impossible budget: {config.sessions} sessions of {config.reward_batch} questions "
            f"every {config.feedback_frequency} steps from step {config.first_session_step} "
            f"end at step {last_session}, but the run has only {config.steps} steps; "
            "raise --steps or --reward-batch, or lower --max-feedback or --feedback-frequency"
        )


def _check_baseline(config: TrainConfig) -> None:
    """A baseline run (`reward` true or none) asks no questions."""
    if config.backbone != Backbone.PEBBLE:
        raise ValueError(
            f"backbone '{config.backbone}' learns its reward from feedback; reward "
            f"'{config.reward}' asks for none: use backbone pebble"
        )
    if config.teacher_spec.kind != "scripted":
        raise ValueError(
            f"teacher '{config.teacher}' answers questions; reward '{config.reward}' asks "
            "none: leave --teacher out"
        )
