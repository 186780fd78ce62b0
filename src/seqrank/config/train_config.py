"""A run's settings as one frozen type, `TrainConfig`: every field a `seqrank train` option
(`--field-name VALUE`), each choice turned into its type when a config is made, each field
declared with its role and, for a number, its range (`config.roles`). How a config is
resolved and checked is `config.resolve`'s; the rules between settings are `config.rules`'
(both import this module, which imports neither).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import asdict, dataclass, fields
from typing import Any

from seqrank.choices import (
    Augment,
    Backbone,
    CrowdWeighting,
    Device,
    Precision,
    RewardLearner,
    RewardSignal,
    Scale,
    SegmentOrder,
    Selection,
    StopOn,
    TrainingPath,
    parse_choice,
)
from seqrank.config.ranges import (
    COUNT,
    COUNT_FROM_ZERO,
    MAX_SEED,
    POSITIVE,
    SHARE,
    SWITCH,
    UP_TO_ONE,
    Count,
)
from seqrank.config.roles import Role, check_declared, declare, role_of
from seqrank.feedback.checking import Recheck
from seqrank.feedback.overlap import EVIDENCE_UNTIL, OVERLAP
from seqrank.feedback.schemes import SchemeName
from seqrank.feedback.teachers import TeacherSpec, parse_teacher
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
    "segment_order": SegmentOrder,
    "scale": Scale,
    "device": Device,
    "path": TrainingPath,
    "precision": Precision,
    "reward": RewardSignal,
    "augment": Augment,
    "reward_learner": RewardLearner,
    "crowd_weighting": CrowdWeighting,
    "reward_stop_on": StopOn,
}


def plain_number(value: Any) -> Any:
    """A number of another library (numpy's int64, float32, ...) as Python's int or float;
    anything else as it is (a bool, a text: the range check names it)."""
    if isinstance(value, bool) or type(value) in (int, float):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return float(value)
    return value


@dataclass(frozen=True)
class TrainConfig:
    """Every setting of a run: the options of `seqrank train`, its config.json and presets.

    Each field is the `seqrank train` option of the same name with - for _, and
    `seqrank train --help` gives each one's meaning and default. Make one with
    `make_config` (Table 2, the size preset, validation); `TrainConfig(...)` itself checks
    only the choices and the teacher. Each field is declared with its role (what part of
    a run it configures, `config.Role`) and, for a number, the values it accepts.

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

    task: str = declare(Role.RUN, "walker_walk")
    scheme: SchemeName = declare(Role.FEEDBACK, SchemeName.SEQUENTIAL)
    # a `parse_teacher` value: preset[,knob=value...], replay:FILE, human
    teacher: str = declare(Role.FEEDBACK, "oracle")
    # `true` and `none` are the baselines
    reward: RewardSignal = declare(Role.RUN, RewardSignal.LEARNED)
    backbone: Backbone = declare(Role.AGENT, Backbone.PEBBLE)
    seed: int = declare(Role.RUN, 0, Count(low=0, high=MAX_SEED))
    steps: int = declare(Role.SCHEDULE, 500_000, COUNT)
    device: Device = declare(Role.RUN, Device.AUTO)
    scale: Scale = declare(Role.RUN, Scale.PAPER)
    path: TrainingPath = declare(Role.AGENT, TrainingPath.AUTO)
    precision: Precision = declare(Role.AGENT, Precision.AUTO)
    # SAC (SPEC section 2)
    hidden: int = declare(Role.AGENT, 1024, COUNT)
    layers: int = declare(Role.AGENT, 2, COUNT)
    batch: int = declare(Role.AGENT, 1024, COUNT)
    actor_lr: float = declare(Role.AGENT, 5e-4, POSITIVE)
    critic_lr: float = declare(Role.AGENT, 5e-4, POSITIVE)
    alpha_lr: float = declare(Role.AGENT, 1e-4, POSITIVE)
    init_temperature: float = declare(Role.AGENT, 0.1, POSITIVE)
    discount: float = declare(Role.AGENT, 0.99, UP_TO_ONE)
    tau: float = declare(Role.AGENT, 0.005, UP_TO_ONE)
    target_update_every: int = declare(Role.AGENT, 2, COUNT)
    # schedule (SPEC section 1): the random warm-up, then pre-training
    seed_steps: int = declare(Role.SCHEDULE, 1_000, COUNT_FROM_ZERO)
    unsup_steps: int = declare(Role.PRETRAINING, 9_000, COUNT_FROM_ZERO)
    knn_k: int = declare(Role.PRETRAINING, 5, COUNT)
    updates_after_reset: int = declare(Role.PRETRAINING, 100, COUNT_FROM_ZERO)
    # feedback (SPEC sections 3 and 8)
    max_feedback: int = declare(Role.FEEDBACK, 400, COUNT)
    reward_batch: int = declare(Role.FEEDBACK, 40, COUNT)
    feedback_frequency: int = declare(Role.FEEDBACK, 20_000, COUNT)
    segment_length: int = declare(Role.FEEDBACK, 50, COUNT)
    # noise-aware augmentation (seqrank.feedback.checking): `checked` asks again an answer
    # that would imply `recheck_gain` new pairs or more (twice from `recheck_twice_gain`
    # once the teacher has contradicted themselves; not at all where the fitted reward model
    # agrees with a teacher who never has), and infers only along paths of at most
    # `path_unchecked` unconfirmed answers
    augment: Augment = declare(Role.FEEDBACK, Augment.FULL)
    recheck_gain: int = declare(Role.FEEDBACK, Recheck.gain, COUNT)
    recheck_twice_gain: int = declare(Role.FEEDBACK, Recheck.twice_gain, COUNT)
    path_unchecked: int = declare(Role.FEEDBACK, Recheck.path_unchecked, COUNT_FROM_ZERO)
    selection: Selection = declare(Role.FEEDBACK, Selection.UNIFORM)
    # a session's new segments as drawn, or in the order they were collected
    segment_order: SegmentOrder = declare(Role.FEEDBACK, SegmentOrder.UNIFORM)
    # each session allocates at once a candidate pool this many times what the scheme needs
    oversample: int = declare(Role.FEEDBACK, 10, Count(high=100))
    episodes_kept: int = declare(Role.FEEDBACK, 100, COUNT)
    # query-policy alignment (QPA)
    # Hu et al., ICLR 2024; off by default. Their values: query_episodes 10 (DMControl),
    # hybrid_replay 0.5, hybrid_episodes 10 (sources: `feedback/session.py`,
    # `agents/hybrid_replay.py`)
    # 0: segments from every kept episode; N: from the last N only
    query_episodes: int = declare(Role.FEEDBACK, 0, COUNT_FROM_ZERO)
    # share of each agent batch from recent transitions; 0: off
    hybrid_replay: float = declare(Role.AGENT_FOR_FEEDBACK, 0.0, SHARE)
    # hybrid replay's recent window, in episodes of the task
    hybrid_episodes: int = declare(Role.AGENT_FOR_FEEDBACK, 10, COUNT)
    # a crowd of annotators (`--teacher crowd:...`; `seqrank.feedback.crowd`): the share of
    # answers also asked of a second person, and how the labels count in reward training
    # (weighting by reliability lost accuracy; a flagged member's labels dropped did not:
    # results/crowd/)
    overlap: float = declare(Role.FEEDBACK, OVERLAP, SHARE)
    # every answer of a member with fewer answers than this shared with someone else is
    # asked again of two others (`feedback.overlap`: evidence for the flags early); 0:
    # `overlap` only
    overlap_until: int = declare(Role.FEEDBACK, EVIDENCE_UNTIL, Count(low=0, high=10_000))
    # 1: a second opinion asks a pair the owner's chain's closure inferred, where there is
    # one (`feedback.closure_checks`: one answer checks several)
    closure_checks: int = declare(Role.FEEDBACK, 0, SWITCH)
    crowd_weighting: CrowdWeighting = declare(Role.FEEDBACK, CrowdWeighting.DROP)
    # a team at the labelling page (`label online`): name,name,...
    annotators: str = declare(Role.FEEDBACK, "")
    # 1: keep physics states so labelled segments can be re-rendered
    record_states: int = declare(Role.FEEDBACK, 0, SWITCH)
    # fine-tuning (the user study's first kind): a saved run's agent, reward model, replay
    # buffer and episodes to start from, and what the sessions' clips show (fresh episodes
    # of the agent, `config.rules.FINETUNE_PARTS`)
    start_from: str = declare(Role.BOOKKEEPING, "")
    parts: str = declare(Role.AGENT_FOR_FEEDBACK, "")
    # reward model (SPEC section 5)
    reward_ensemble: int = declare(Role.REWARD_MODEL, 3, COUNT)
    reward_hidden: int = declare(Role.REWARD_MODEL, 256, COUNT)
    reward_layers: int = declare(Role.REWARD_MODEL, 3, COUNT)
    reward_lr: float = declare(Role.REWARD_TRAINING, 3e-4, POSITIVE)
    reward_minibatch: int = declare(Role.REWARD_TRAINING, 128, COUNT)
    reward_epochs: int = declare(Role.REWARD_TRAINING, 50, COUNT)
    reward_stop_accuracy: float = declare(Role.REWARD_TRAINING, 0.97, UP_TO_ONE)
    # which labels that accuracy counts
    reward_stop_on: StopOn = declare(Role.REWARD_TRAINING, StopOn.ALL)
    # reward learners beyond the paper (SURF, RIME): docs/concepts/reward-learners.md; the
    # defaults and their sources are in `SurfSettings` and `RimeSettings`; SURF's
    # unlabelled pairs are per question asked, cut each fit
    reward_learner: RewardLearner = declare(Role.REWARD_TRAINING, RewardLearner.PLAIN)
    surf_threshold: float = declare(Role.REWARD_TRAINING, SurfSettings.threshold, UP_TO_ONE)
    surf_unlabelled_ratio: int = declare(
        Role.REWARD_TRAINING, SurfSettings.unlabelled_ratio, Count(high=1_000)
    )
    surf_unlabelled_batch: int = declare(
        Role.REWARD_TRAINING, SurfSettings.unlabelled_batch, Count(high=100)
    )
    surf_loss_weight: float = declare(Role.REWARD_TRAINING, SurfSettings.loss_weight, POSITIVE)
    surf_crop: int = declare(Role.REWARD_TRAINING, SurfSettings.crop, COUNT_FROM_ZERO)
    rime_alpha: float = declare(Role.REWARD_TRAINING, RimeSettings.alpha, POSITIVE)
    rime_beta_max: float = declare(Role.REWARD_TRAINING, RimeSettings.beta_max, POSITIVE)
    rime_beta_min: float = declare(Role.REWARD_TRAINING, RimeSettings.beta_min, POSITIVE)
    rime_decay_updates: int = declare(Role.REWARD_TRAINING, RimeSettings.decay_updates, COUNT)
    rime_tau_upper: float = declare(Role.REWARD_TRAINING, RimeSettings.tau_upper, UP_TO_ONE)
    rime_min_epochs: int = declare(Role.REWARD_TRAINING, RimeSettings.min_epochs, COUNT)
    # 1: RIME's warm start of the reward model in pre-training
    warm_start: int = declare(Role.REWARD_TRAINING, 0, SWITCH)
    # MRN (SPEC section 7)
    meta_update_frequency: int = declare(Role.AGENT_FOR_FEEDBACK, 1_000, COUNT)
    meta_loss_weight: float = declare(Role.AGENT_FOR_FEEDBACK, 0.1, POSITIVE)
    # evaluation, logging, checkpoints
    eval_every: int = declare(Role.BOOKKEEPING, 10_000, COUNT)
    eval_episodes: int = declare(Role.BOOKKEEPING, 10, COUNT)
    checkpoint_every: int = declare(Role.BOOKKEEPING, 10_000, COUNT)
    # the reward model's held-out measure: pairs each session allocates at once
    heldout_pairs: int = declare(Role.REWARD_TRAINING, 500, Count(high=100_000))

    def __post_init__(self) -> None:
        for f in fields(self):  # numpy's numbers as Python's: a config is saved as JSON
            if f.type in ("int", "float"):
                object.__setattr__(self, f.name, plain_number(getattr(self, f.name)))
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


check_declared(TrainConfig)  # a setting without a role fails here, not in a list that missed it
# each setting's role, in the fields' order
ROLES: dict[str, Role] = {f.name: role_of(f) for f in fields(TrainConfig)}


def settings_of(*roles: Role) -> frozenset[str]:
    """The settings of these roles."""
    return frozenset(name for name, role in ROLES.items() if role in roles)
