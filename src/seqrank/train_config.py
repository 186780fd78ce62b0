"""A run's settings as one frozen type, `TrainConfig`: every field a `seqrank train` option
(`--field-name VALUE`), each choice turned into its type when a config is made. How a config
is resolved and checked is `seqrank.config`'s; the rules between settings are
`seqrank.config_rules`' (both import this module, which imports neither).
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
    Selection,
    StopOn,
    TrainingPath,
    parse_choice,
)
from seqrank.feedback.checking import Recheck
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
    crowd_weighting: CrowdWeighting = CrowdWeighting.NONE  # weighting lost accuracy: results/crowd/
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
    reward_stop_on: StopOn = StopOn.ALL  # which labels that accuracy counts
    # reward learners beyond the paper (SURF, RIME): docs/concepts/reward-learners.md; the defaults
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
