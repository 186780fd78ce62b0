"""An offline run's settings: `seqrank offline train`'s options, its `config.json` and the
Python API's keywords at once.

The learner's defaults are IQL's published MuJoCo hyperparameters (Kostrikov et al. 2022,
`configs/mujoco_config.py` of the authors' code): expectile 0.7, temperature 3.0, discount
0.99, learning rates 3e-4, batch 256, two hidden layers of 256, 1M updates, target rate
0.005, the actor's rate on a cosine schedule. LiRE (Choi et al. 2024, `configs/iql.yaml`)
runs IQL on Meta-World with the same values, 250k updates and 50 evaluation episodes
every 5 000; its reward scaling is `reward_scale` "unit" (`offline.rewards`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from enum import StrEnum
from pathlib import Path
from typing import Any

from seqrank.agents.iql_settings import IQLSettings
from seqrank.errors import SettingError, setting

_IQL = IQLSettings()  # IQL's published hyperparameters, the learner's defaults


class OfflineReward(StrEnum):
    TRUE = "true"  # the dataset's own reward: the ceiling a learned reward is held to
    LEARNED = "learned"  # labels over the dataset's segments, a reward model, relabelled


class RewardScale(StrEnum):
    """How the rewards IQL trains on are scaled (`offline.rewards.scale_rewards`)."""

    AUTO = "auto"  # unit on Meta-World (LiRE), returns elsewhere (IQL's locomotion)
    RETURNS = "returns"  # x 1000 / (max episode return - min episode return): IQL, MuJoCo
    UNIT = "unit"  # per-step min-max onto [0, 1]: LiRE, Meta-World
    NONE = "none"


# what a learned reward is asked with: a run on the dataset's own reward takes none of them
LEARNED_ONLY = ("scheme", "teacher", "max_feedback", "segment_length", "session_questions")


@dataclass(frozen=True)
class OfflineConfig:
    dataset: str  # a Minari dataset id or a dataset folder (`offline.minari_io.locate`)
    task: str | None = None  # the task the dataset must be of; None: the one it records
    reward: str = "true"  # OfflineReward
    scheme: str = "sequential"  # learned: the comparison scheme asked over the segments
    teacher: str = "oracle"  # learned: who answers (`seqrank train --teacher`'s values)
    max_feedback: int = 500  # learned: the questions asked in all
    segment_length: int = 50  # learned: steps a segment (`offline.labelling`'s default)
    session_questions: int = 25  # learned: questions a session
    steps: int = 1_000_000  # IQL updates
    eval_every: int = 5_000  # updates between evaluations (each one checkpoints)
    eval_episodes: int = 10
    seed: int = 0
    batch: int = 256
    # the learner's, IQL's published values (`agents.iql_settings`)
    hidden: int = _IQL.hidden
    layers: int = _IQL.layers
    actor_lr: float = _IQL.actor_lr
    critic_lr: float = _IQL.critic_lr
    value_lr: float = _IQL.value_lr
    discount: float = _IQL.discount
    expectile: float = _IQL.expectile
    temperature: float = _IQL.temperature
    target_rate: float = _IQL.target_rate
    reward_scale: str = "auto"  # RewardScale
    normalize_observations: bool = True  # by the dataset's mean and std (LiRE's IQL)
    device: str = "auto"
    log_every: int = 1_000  # updates between `train` rows

    def as_dict(self) -> dict[str, Any]:
        """The settings as `config.json` records them: a true-reward run's learned-reward
        settings are null (it asks no question; the CLI refuses them)."""
        values = asdict(self)
        if self.reward == OfflineReward.TRUE.value:
            values.update(dict.fromkeys(LEARNED_ONLY))
        return values

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> OfflineConfig:
        """Settings read back from a `config.json` (keys it does not know are refused; a
        learned-reward setting recorded null takes its default, as `as_dict` writes a
        true-reward run's)."""
        values = {k: v for k, v in values.items() if not (k in LEARNED_ONLY and v is None)}
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise SettingError(
                f"unknown setting {setting(unknown[0])}; an offline run's settings are "
                f"{', '.join(sorted(known))}"
            )
        return cls(**values)

    def iql(self) -> IQLSettings:
        """The learner's settings: each of IQL's this config names, and the actor's rate
        reaching 0 at the run's last update."""
        shared = {f.name for f in fields(IQLSettings)} & {f.name for f in fields(self)}
        return IQLSettings(**{name: getattr(self, name) for name in shared}, decay_steps=self.steps)


def new_config(values: dict[str, Any]) -> OfflineConfig:
    """A new run's settings from those a user gave (options or keywords; the rest take
    their defaults): learned-reward settings beside the true reward are refused, a
    `replay:FILE` teacher's scheme, segment length, session size and budget come from its
    file (given otherwise: refused), and a dataset folder is named by its absolute path (a
    resumed run finds it from anywhere)."""
    config = OfflineConfig.from_dict(values)
    given = set(values)
    if not str(config.dataset).strip():
        raise SettingError(f"{setting('dataset')} must name a dataset, got an empty value")
    if config.reward == OfflineReward.TRUE.value:
        extra = [setting(name) for name in LEARNED_ONLY if name in given]
        if extra:
            raise SettingError(
                f"{', '.join(extra)} {'act' if len(extra) > 1 else 'acts'} on a learned reward; "
                f"{setting('reward')} true trains on the dataset's own: leave "
                f"{'them' if len(extra) > 1 else 'it'} out, or give {setting('reward')} learned"
            )
    if Path(config.dataset).exists():
        config = replace(config, dataset=str(Path(config.dataset).resolve()))
    return _replayed(config, given)


def _replayed(config: OfflineConfig, given: set[str]) -> OfflineConfig:
    from seqrank.config.rules import recorded_values, replayed

    if config.teacher.strip().lower() == "human":
        raise SettingError(
            f"{setting('teacher')} 'human' answers on the labelling page: label the dataset "
            "there (seqrank label offline --dataset ...), then train on its labels.jsonl "
            f"with {setting('teacher')} replay:FILE"
        )
    recorded = replayed(config.teacher)
    if recorded is None:
        return config
    taken = recorded_values(recorded, config.max_feedback if "max_feedback" in given else None)
    taken["session_questions"] = taken.pop("reward_batch")
    taken.pop("task", None)
    for name, value in taken.items():
        if name in given and name != "max_feedback" and getattr(config, name) != value:
            raise SettingError(
                f"{setting(name)} {getattr(config, name)} conflicts with the replay file's "
                f"{value} ({recorded.file}); leave {setting(name)} out to take the file's"
            )
    if config.max_feedback > recorded.answers and "max_feedback" in given:
        raise SettingError(
            f"{setting('max_feedback')} {config.max_feedback} is more than the "
            f"{recorded.answers} answers of {recorded.file}; accepted: 1 to {recorded.answers}, "
            f"or leave {setting('max_feedback')} out to replay them all"
        )
    if "max_feedback" in given:
        taken.pop("max_feedback")
    return replace(config, **taken)


# the least and the largest value of each whole-number setting (`batch` is held to the
# dataset's transitions too, once it is read: `offline.launch.load_checked`)
_MOST = 2**31 - 1  # `config.ranges.MAX_COUNT`, online `train`'s
_WHOLE = {
    "max_feedback": (1, _MOST),
    "segment_length": (1, _MOST),
    "session_questions": (1, _MOST),
    "steps": (1, 10**9),
    "eval_every": (1, 10**9),
    "eval_episodes": (1, 10_000),
    "batch": (1, _MOST),
    "hidden": (1, 4096),
    "layers": (1, 64),
    "log_every": (1, 10**9),
}
_RATES = ("actor_lr", "critic_lr", "value_lr", "target_rate")  # in (0, 1]


def validate(config: OfflineConfig) -> OfflineConfig:
    """The config, or a SettingError naming the first setting out of range."""
    from seqrank.feedback.schemes import SchemeName
    from seqrank.feedback.teachers import parse_teacher

    if not str(config.dataset).strip():
        raise SettingError(f"{setting('dataset')} must name a dataset")
    _choice(OfflineReward, config.reward, "reward")
    _choice(RewardScale, config.reward_scale, "reward_scale")
    _choice(SchemeName, config.scheme, "scheme")
    parse_teacher(config.teacher)
    if not 0 <= config.seed < 2**32:
        raise SettingError(f"{setting('seed')} must lie in 0 to 2**32 - 1, got {config.seed}")
    for name, (lowest, highest) in _WHOLE.items():
        value = getattr(config, name)
        if isinstance(value, bool) or not isinstance(value, int) or not lowest <= value <= highest:
            raise SettingError(
                f"{setting(name)} must be a whole number from {lowest} to {highest}, got {value!r}"
            )
    for name in _RATES:
        _number(config, name, lambda v: 0 < v <= 1, "in (0, 1]")
    _number(config, "expectile", lambda v: 0 < v < 1, "strictly between 0 and 1")
    _number(config, "discount", lambda v: 0 <= v <= 1, "in [0, 1]")
    _number(config, "temperature", lambda v: v >= 0, ">= 0 (0 is behaviour cloning)")
    if not isinstance(config.normalize_observations, bool):
        raise SettingError(f"{setting('normalize_observations')} must be true or false")
    if config.device not in ("auto", "cpu", "cuda"):
        raise SettingError(
            f"unknown {setting('device')} {config.device!r}; accepted: auto, cpu, cuda"
        )
    return config


def _choice(kind: type[StrEnum], value: object, name: str) -> None:
    accepted = [member.value for member in kind]
    if value not in accepted:
        raise SettingError(f"unknown {setting(name)} {value!r}; accepted: {', '.join(accepted)}")


def _number(config: OfflineConfig, name: str, fits: Any, what: str) -> None:
    value = getattr(config, name)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise SettingError(f"{setting(name)} must be a number {what}, got {value!r}")
    if not fits(value):
        raise SettingError(f"{setting(name)} must be {what}, got {value}")
