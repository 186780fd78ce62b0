"""Scripted teachers with the B-Pref knobs (Lee et al. 2021), applied in SPEC section 4 order.

A teacher answers "is segment A preferred to segment B?" from the true per-step rewards
of both segments. The knobs, in the order they act:

1. skip     drop the pair when max(sum r_A, sum r_B) <= eps_skip * margin (only if eps_skip > 0)
2. equal    mark the pair when |sum r_A - sum r_B| < eps_equal * margin
3. myopia   weight step t by gamma ** (H - 1 - t) before summing
4. rationality  beta <= 0 or inf: deterministic; else P(A) = sigmoid(beta * (S_A - S_B))
5. mistake  flip the answer with probability eps_mistake
6. pairs marked at step 2 are answered EQUAL

`margin` is the mean true return of recent training episodes scaled to segment length
(mean episode return * H / episode length). It is a plain value passed by the caller each
session: it is never squared or otherwise changed between sessions (the reference code
squares eps after its first session; that is a bug this module does not reproduce).

Exact ties of the (myopic) sums under a deterministic teacher follow `tie_rule`:
"equal" (default) answers EQUAL, "first" prefers A (B-Pref's silent behaviour),
"random" flips a fair coin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from seqrank.errors import SettingError, setting
from seqrank.types import Answer

TieRule = Literal["equal", "first", "random"]
TIE_RULES: tuple[TieRule, ...] = ("equal", "first", "random")


@dataclass(frozen=True)
class TeacherConfig:
    """B-Pref teacher knobs. Defaults are the perfect (oracle) teacher."""

    beta: float = math.inf
    gamma: float = 1.0
    eps_mistake: float = 0.0
    eps_skip: float = 0.0
    eps_equal: float = 0.0
    tie_rule: TieRule = "equal"

    def __post_init__(self) -> None:
        if math.isnan(self.beta):
            raise SettingError(
                f"{setting('teacher')} beta must be a number (<= 0 or inf means deterministic)"
            )
        if not 0.0 < self.gamma <= 1.0:
            raise SettingError(f"{setting('teacher')} gamma must be in (0, 1], got {self.gamma}")
        for name in ("eps_mistake", "eps_skip", "eps_equal"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise SettingError(f"{setting('teacher')} {name} must be in [0, 1], got {value}")
        if self.tie_rule not in TIE_RULES:
            raise SettingError(
                f"{setting('teacher')} tie_rule {self.tie_rule!r} is not one of "
                f"{', '.join(TIE_RULES)}"
            )

    @property
    def deterministic(self) -> bool:
        return self.beta <= 0 or math.isinf(self.beta)


TEACHER_PRESETS: dict[str, TeacherConfig] = {
    "oracle": TeacherConfig(),
    "mistake": TeacherConfig(eps_mistake=0.1),
    "noisy": TeacherConfig(beta=1.0),
    "skip": TeacherConfig(eps_skip=0.1),
    "myopic": TeacherConfig(gamma=0.9),
    "equal": TeacherConfig(eps_equal=0.1),
}


def teacher_preset(name: str) -> TeacherConfig:
    """The named B-Pref preset; a ValueError names the accepted presets."""
    try:
        return TEACHER_PRESETS[name]
    except KeyError:
        accepted = ", ".join(TEACHER_PRESETS)
        raise ValueError(f"unknown teacher preset {name!r}; accepted: {accepted}") from None


@dataclass(frozen=True)
class ScriptedTeacher:
    """Answers comparisons of two segments from their true per-step rewards."""

    config: TeacherConfig
    margin: float = 0.0

    def with_margin(self, margin: float) -> ScriptedTeacher:
        """The same teacher with a new margin (call once per feedback session)."""
        return replace(self, margin=float(margin))

    def answer(
        self, rewards_a: np.ndarray, rewards_b: np.ndarray, rng: np.random.Generator
    ) -> Answer:
        cfg = self.config
        return_a, return_b = float(np.sum(rewards_a)), float(np.sum(rewards_b))
        if cfg.eps_skip > 0 and max(return_a, return_b) <= cfg.eps_skip * self.margin:
            return Answer.SKIP
        marked_equal = abs(return_a - return_b) < cfg.eps_equal * self.margin
        score_a = _myopic_sum(rewards_a, cfg.gamma)
        score_b = _myopic_sum(rewards_b, cfg.gamma)
        answer = _rational_choice(score_a, score_b, cfg, rng)
        if cfg.eps_mistake > 0 and rng.random() < cfg.eps_mistake:
            answer = answer.flipped()
        return Answer.EQUAL if marked_equal else answer


def _myopic_sum(rewards: np.ndarray, gamma: float) -> float:
    rewards = np.asarray(rewards, dtype=np.float64)
    if gamma == 1.0:
        return float(rewards.sum())
    horizon = rewards.shape[0]
    weights = gamma ** np.arange(horizon - 1, -1, -1, dtype=np.float64)
    return float(np.dot(weights, rewards))


def _rational_choice(
    score_a: float, score_b: float, cfg: TeacherConfig, rng: np.random.Generator
) -> Answer:
    if not cfg.deterministic:
        logit = cfg.beta * (score_a - score_b)
        prob_a = 1.0 / (1.0 + math.exp(-logit)) if logit > -700 else 0.0
        return Answer.FIRST if rng.random() < prob_a else Answer.SECOND
    if score_a > score_b:
        return Answer.FIRST
    if score_b > score_a:
        return Answer.SECOND
    if cfg.tie_rule == "equal":
        return Answer.EQUAL
    if cfg.tie_rule == "first":
        return Answer.FIRST
    return Answer.FIRST if rng.random() < 0.5 else Answer.SECOND


KNOBS = ("beta", "gamma", "eps_mistake", "eps_skip", "eps_equal", "tie_rule")


@dataclass(frozen=True)
class TeacherSpec:
    """Who answers a run's questions, parsed once from the `--teacher` value:

    - a scripted teacher: a preset (`oracle`, `mistake`, ...), optionally with B-Pref knobs
      changed (`mistake,eps_mistake=0.2`), or knobs alone from the oracle
      (`beta=1,gamma=0.95`); knobs: beta, gamma, eps_mistake, eps_skip, eps_equal, tie_rule;
    - `replay:FILE`: labels exported earlier, replayed session by session;
    - `crowd:oracle+mistake+noisy`: a simulated crowd of scripted annotators sharing each
      session (`seqrank.feedback.crowd`);
    - `human`: a person at the labelling page (`seqrank label online`).
    """

    kind: Literal["scripted", "replay", "human", "crowd"]
    scripted: TeacherConfig | None = None
    replay_file: str | None = None
    short_name: str = "oracle"  # for run directory names: a preset, custom, replay, human
    members: tuple[CrowdMember, ...] = ()  # a simulated crowd's (`crowd:oracle+noisy`)


@dataclass(frozen=True)
class CrowdMember:
    """One scripted annotator of a simulated crowd, who takes `seconds` an answer."""

    name: str
    teacher: TeacherConfig
    seconds: float = 3.0


CROWD_PREFIX = "crowd:"
MEMBER_KNOBS = ("name", "time")  # beside the B-Pref knobs, in a crowd member only


def parse_crowd(value: str) -> TeacherSpec:
    """`crowd:MEMBER+MEMBER+...`, each member a scripted teacher as `--teacher` takes it,
    optionally with `time=SECONDS` (its answer time, 3 by default) and `name=NAME`;
    unnamed members are called by their preset (`oracle`, `oracle-2`, ...)."""
    body = value.removeprefix(CROWD_PREFIX)
    members: list[CrowdMember] = []
    for text in body.split("+"):
        if not text.strip():
            raise SettingError(
                f"{setting('teacher')} {value!r}: an empty crowd member; write members as "
                "crowd:oracle+mistake+noisy (each a preset, optionally with ,knob=value)"
            )
        members.append(_crowd_member(text.strip(), value, [m.name for m in members]))
    short = "crowd-" + "+".join(m.name for m in members)
    return TeacherSpec("crowd", short_name=short, members=tuple(members))


def _crowd_member(text: str, value: str, taken: list[str]) -> CrowdMember:
    parts = [part.strip() for part in text.split(",")]
    extra = {p.partition("=")[0].strip(): p.partition("=")[2].strip() for p in parts if "=" in p}
    teacher = ",".join(p for p in parts if p.partition("=")[0].strip() not in MEMBER_KNOBS)
    also = "; a crowd member also takes time= and name="
    spec = parse_scripted_teacher(teacher or "oracle", also)
    assert spec.scripted is not None
    preset = parts[0] if parts and "=" not in parts[0] else "member"  # (knobs alone: member)
    name = extra.get("name", preset)
    if "name" in extra and (not name or name in taken or not name.replace("-", "").isalnum()):
        raise SettingError(
            f"{setting('teacher')} {value!r}: member name {name!r} must be letters, digits "
            f"and '-', unique in the crowd (taken: {', '.join(taken) or 'none'})"
        )
    if "name" not in extra:
        base, number = name, 2
        while name in taken:
            name, number = f"{base}-{number}", number + 1
    seconds = _member_seconds(extra.get("time", "3"), value)
    return CrowdMember(name, spec.scripted, seconds)


def _member_seconds(text: str, value: str) -> float:
    try:
        seconds = float(text)
    except ValueError:
        seconds = math.nan
    if not (math.isfinite(seconds) and seconds > 0):
        raise SettingError(
            f"{setting('teacher')} {value!r}: time must be a number of seconds > 0, got {text!r}"
        )
    return seconds


def parse_teacher(value: str) -> TeacherSpec:
    """The spec `value` stands for; a ValueError names what is wrong and what is accepted."""
    if value == "human":
        return TeacherSpec("human", short_name="human")
    if value.startswith(CROWD_PREFIX):
        return parse_crowd(value)
    if value.startswith("replay:"):
        path = value.removeprefix("replay:")
        if not path:
            raise SettingError(
                f"{setting('teacher')} 'replay:' needs a file: replay:PATH/TO/labels.jsonl"
            )
        return TeacherSpec("replay", replay_file=path, short_name="replay")
    others = (
        ", knob=value,..., human (the labelling page), replay:FILE (labels exported as "
        "JSONL) or crowd:MEMBER+MEMBER (a simulated crowd)"
    )
    return parse_scripted_teacher(value, others)


def parse_scripted_teacher(value: str, others: str = " or knob=value,...") -> TeacherSpec:
    """A scripted teacher's spec: a preset, optionally with knobs, or knobs alone; `others`
    ends the list of what is accepted in the error (the caller's other kinds of teacher)."""
    parts = [part.strip() for part in value.split(",")]
    base, name = TeacherConfig(), "custom"
    if parts and "=" not in parts[0]:
        name = parts.pop(0)
        if name not in TEACHER_PRESETS:
            raise SettingError(
                f"unknown {setting('teacher')} {name!r}; accepted: {', '.join(TEACHER_PRESETS)} "
                f"(optionally followed by ,knob=value){others}"
            )
        base = TEACHER_PRESETS[name]
    knobs = dict(_knob(part, value) for part in parts)
    short = name if not knobs else "custom"
    return TeacherSpec("scripted", replace(base, **knobs), short_name=short)  # type: ignore[arg-type]


def scripted_config(value: str) -> TeacherConfig:
    """The knobs of the scripted teacher `value` names (a preset, knobs, or both)."""
    config = parse_scripted_teacher(value).scripted
    assert config is not None  # a scripted spec always has its knobs
    return config


TEACHER_SEPARATOR = ";"


def split_teachers(text: str) -> list[str]:
    """The teachers of one option value that lists several (`--teachers`), each as
    `parse_teacher` reads it: separated by `;`, or by a comma whose next part is not a
    knob, since a `knob=value` part belongs to the teacher before it. So `oracle,noisy`
    and `mistake,eps_mistake=0.2,oracle` are two teachers each, and `;` separates what
    commas cannot: `beta=1;beta=2`, `oracle;gamma=0.95`. A ValueError names an empty one."""
    teachers: list[str] = []
    for group in text.split(TEACHER_SEPARATOR):
        first = len(teachers)
        for part in (p.strip() for p in group.split(",")):
            if not part:
                raise ValueError(f"{text!r}: an empty teacher between separators")
            if "=" in part and len(teachers) > first:
                teachers[-1] += f",{part}"
            else:
                teachers.append(part)
    return teachers


def _knob(part: str, value: str) -> tuple[str, float | str]:
    key, _, text = part.partition("=")
    key = key.strip()
    if key not in KNOBS:
        raise SettingError(
            f"{setting('teacher')} {value!r}: unknown knob {key!r}; knobs: {', '.join(KNOBS)}"
        )
    if not text:
        raise SettingError(f"{setting('teacher')} {value!r}: {part!r} is not knob=value")
    if key == "tie_rule":
        return key, text.strip()
    try:
        return key, float(text)
    except ValueError:
        raise SettingError(
            f"{setting('teacher')} {value!r}: {key} must be a number, got {text!r}"
        ) from None
