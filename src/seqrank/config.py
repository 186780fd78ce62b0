"""One frozen config per run: the CLI options, the saved config.json and the presets at once.

`resolve_config(task, scale, overrides)` starts from the suite defaults (SPEC section 2),
applies the task's row of the paper's Table 2, then the size preset, then the user's
overrides. Every field is a `seqrank train` option (`--field-name VALUE`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from seqrank import config_rules as rules
from seqrank.choices import (
    Augment,
    Backbone,
    CrowdWeighting,
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
from seqrank.config_ranges import check_setting
from seqrank.envs import canonical_task
from seqrank.errors import SettingError, setting
from seqrank.feedback.checking import Recheck
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
    "augment": Augment,
    "reward_learner": RewardLearner,
    "crowd_weighting": CrowdWeighting,
}


@dataclass(frozen=True)
class TrainConfig:
    """Every setting of a run: the options of `seqrank train`, its config.json and presets.

    Each field is the `seqrank train` option of the same name with - for _, and
    `seqrank train --help` gives each one's meaning and default. Make one with
    `make_config` (Table 2, the size preset, validation); `TrainConfig(...)` itself checks
    only the choices and the teacher.

    Attributes:
        task: as `--task` takes it: walker_walk, dmc:..., metaworld:..., block:place,
            gym:ID or module.path:factory.
        scheme: how a session asks: pairwise, sequential, root or ranked.
        teacher: who answers: a scripted preset with B-Pref knobs (oracle, mistake, ...),
            replay:FILE, human, or a crowd (crowd:oracle+mistake).
        reward: what the agent learns from: learned (the method), true or none (baselines).
        backbone: pebble (SAC) or mrn (MRN's bi-level reward learning).
        seed: seeds every random stream of the run (episodes, agent, sessions).
        steps: environment steps of the run.
        max_feedback: the run's budget of questions.
        reward_batch: questions per session.
        feedback_frequency: steps between sessions.
        augment: full (the paper's closure) or checked (noise-aware, see `recheck`).
        selection: which segments a session compares: uniform, disagreement or entropy.
        reward_learner: plain (Bradley-Terry, PEBBLE's), surf or rime.
        device: auto (CUDA when there is one), cpu or cuda.

    Examples:
        >>> import seqrank
        >>> config = seqrank.make_config("walker_walk", teacher="mistake", augment="checked")
        >>> config.sessions, config.recheck.gain, config.as_dict()["teacher"]
        (5, 1, 'mistake')
    """

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
    # noise-aware augmentation (seqrank.feedback.checking): `checked` asks again an answer
    # that would imply `recheck_gain` new pairs or more (twice from `recheck_twice_gain`
    # once the teacher has contradicted themselves; not at all where the fitted reward model
    # agrees with a teacher who never has), and infers only along paths of at most
    # `path_unchecked` unconfirmed answers
    augment: Augment = Augment.FULL
    recheck_gain: int = Recheck.gain
    recheck_twice_gain: int = Recheck.twice_gain
    path_unchecked: int = Recheck.path_unchecked
    selection: Selection = Selection.UNIFORM
    oversample: int = 10
    episodes_kept: int = 100
    # query-policy alignment (QPA)
    # Hu et al., ICLR 2024; off by default. Their values: query_episodes 10 (DMControl),
    # hybrid_replay 0.5, hybrid_episodes 10 (sources: `feedback/session.py`,
    # `agents/hybrid_replay.py`)
    query_episodes: int = 0  # 0: segments from every kept episode; N: from the last N only
    hybrid_replay: float = 0.0  # share of each agent batch from recent transitions; 0: off
    hybrid_episodes: int = 10  # hybrid replay's recent window, in episodes of the task
    # a crowd of annotators (`--teacher crowd:...`; `seqrank.feedback.crowd`): the share of
    # answers also asked of a second person, and how the labels count in reward training
    overlap: float = 0.1
    crowd_weighting: CrowdWeighting = CrowdWeighting.RELIABILITY
    annotators: str = ""  # a team at the labelling page (`label online`): name,name,...
    record_states: int = 0  # 1: keep physics states so labelled segments can be re-rendered
    # fine-tuning (the user study's first kind): a saved run's agent, reward model, replay
    # buffer and episodes to start from, and what the sessions' clips show
    # (`config_rules.FINETUNE_PARTS`)
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
    # reward learners beyond the paper (SURF, RIME): README "Reward learners"; the defaults
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
    rime_min_epochs: int = RimeSettings.min_epochs
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
        """The parsed `teacher`."""
        return parse_teacher(self.teacher)

    @property
    def team(self) -> tuple[str, ...]:
        """Who shares the sessions out: a simulated crowd's members, or the annotators of
        a team at the labelling page; () for one teacher."""
        if self.annotators:
            return tuple(name.strip() for name in self.annotators.split(","))
        return tuple(m.name for m in self.teacher_spec.members)

    @property
    def sessions(self) -> int:
        """Feedback sessions of the run: max_feedback / reward_batch, rounded up."""
        return math.ceil(self.max_feedback / self.reward_batch)

    @property
    def recheck(self) -> Recheck | None:
        """The noise-aware augmentation's settings; None for the paper's closure."""
        if self.augment is Augment.FULL:
            return None
        return Recheck(self.recheck_gain, self.recheck_twice_gain, self.path_unchecked)

    @property
    def first_session_step(self) -> int:
        """The step of the first session: after the seed steps and pre-training."""
        return self.seed_steps + self.unsup_steps

    def as_dict(self) -> dict[str, Any]:
        """The fields as a dict (config.json's content)."""
        return asdict(self)


# The settings a baseline run never reads: its results depend on the others only, so a
# sweep plans it once whatever its variants do to these, and a report pools baseline runs
# that differ in these alone.
# Read only where questions are asked (sessions and what they cut, show and measure the
# model on, reward learners, re-checks, QPA, MRN):
ASKING_ONLY = frozenset(
    {
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
        *(f.name for f in fields(TrainConfig) if f.name.startswith(("surf_", "rime_"))),
    }
)
# Read only when the reward model learns from labels (a no-feedback run's never does):
REWARD_FITTING = frozenset({"reward_minibatch", "reward_epochs", "reward_stop_accuracy"})
# Read only by pre-training, the critic reset after it and the reward model, none of which
# the true-reward agent has:
PRETRAINING_AND_REWARD_MODEL = REWARD_FITTING | {
    "unsup_steps",
    "knn_k",
    "updates_after_reset",
    "warm_start",
    "reward_ensemble",
    "reward_hidden",
    "reward_layers",
    "reward_lr",
}


REWARD_MODEL_SIZES = frozenset({"reward_ensemble", "reward_hidden", "reward_layers"})


def unread_settings(reward: RewardSignal, start_from: bool = False) -> frozenset[str]:
    """The settings a run that learns from `reward` never reads (none for a learned
    reward); `start_from`: the run's own (a run started from a saved one checks the saved
    reward model's sizes against its own)."""
    if reward is RewardSignal.TRUE:
        unread = ASKING_ONLY | PRETRAINING_AND_REWARD_MODEL
        return unread - REWARD_MODEL_SIZES if start_from else unread
    if reward is RewardSignal.NONE:  # (its untrained model is fit to nothing: no warm start)
        return ASKING_ONLY | REWARD_FITTING | {"warm_start", "reward_lr"}
    return frozenset()


def resolve_config(task: str | None, scale: str, overrides: dict[str, Any]) -> TrainConfig:
    """Suite defaults, then Table 2, then the size preset, then what a replayed label file
    fixes (`config_rules.recorded_values`), then the user's overrides, which must agree
    with the file. `task` None: the label file's, else the default."""
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
        if f.type in ("int", "float"):
            check_setting(f.name, str(f.type), getattr(config, f.name))
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
    rules.check_crowd(config)
