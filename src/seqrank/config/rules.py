"""The rules a run's settings must keep together, beyond each setting's own range: each
raises SettingError naming the bad value and what is accepted (called by `validate`; those
of a replayed label file by `resolve_config`, which knows the settings the user gave; both
in `config.resolve`)."""

from __future__ import annotations

import json
import re
import unicodedata
from collections.abc import Collection
from dataclasses import fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from seqrank.choices import Backbone, SegmentOrder, Selection
from seqrank.config.train_config import TrainConfig
from seqrank.envs import canonical_task, same_task
from seqrank.errors import SettingError, setting
from seqrank.feedback.teachers import parse_teacher

if TYPE_CHECKING:
    from seqrank.feedback.replay import Recorded


def check_qpa(config: TrainConfig) -> None:
    """Query-policy alignment narrows where new segments are cut and what agent batches
    hold while feedback is asked for: it needs new segments, and questions."""
    n = config.query_episodes
    if n > config.episodes_kept:
        raise SettingError(
            f"{setting('query_episodes')} {n} exceeds {setting('episodes_kept')} "
            f"{config.episodes_kept}: segments are cut from the last {setting('query_episodes')} "
            f"of the kept episodes; accepted: 0 (all) to {config.episodes_kept}"
        )
    if not config.reward.asks and (n or config.hybrid_replay):
        raise SettingError(
            f"{setting('query_episodes')} and {setting('hybrid_replay')} act while feedback "
            f"is asked for; {setting('reward')} '{config.reward}' asks none: leave them out"
        )
    if n and config.teacher_spec.kind == "replay":
        raise SettingError(
            f"{setting('teacher')} '{config.teacher}' replays recorded segments; "
            f"{setting('query_episodes')} chooses where new segments are cut: leave it out "
            f"({setting('hybrid_replay')} works with replay)"
        )
    if n and config.parts:
        raise SettingError(
            f"{setting('parts')} {config.parts!r} replaces a session's episodes with fresh "
            "ones of the current policy (aligned already, one per skill level); "
            f"{setting('query_episodes')} would drop some: leave it out"
        )


def check_segment_order(config: TrainConfig) -> None:
    """Collection order hands a session's new segments to its scheme as collected: it
    needs new segments, taken as they come."""
    if config.segment_order is SegmentOrder.UNIFORM:
        return
    order = f"{setting('segment_order')} {config.segment_order}"
    if not config.reward.asks:
        raise SettingError(
            f"{order} orders the segments of questions; {setting('reward')} "
            f"'{config.reward}' asks none: leave it out"
        )
    if config.teacher_spec.kind == "replay":
        raise SettingError(
            f"{setting('teacher')} '{config.teacher}' replays recorded segments; {order} "
            "orders new ones: leave it out"
        )
    if config.parts:
        raise SettingError(
            f"{setting('parts')} {config.parts!r} replaces a session's episodes with fresh "
            f"ones ordered by skill level, not by when they were collected; {order} would "
            "take that order for it: leave one out"
        )
    if config.selection is not Selection.UNIFORM:
        raise SettingError(
            f"{order} gives the scheme its segments as they come; {setting('selection')} "
            f"{config.selection} picks among them by the model: keep {setting('selection')} "
            f"uniform with it, or leave {setting('segment_order')} out"
        )


CROWD_SETTINGS = ("overlap", "overlap_until", "closure_checks", "crowd_weighting")


def unread_crowd_settings(config: TrainConfig) -> frozenset[str]:
    """The crowd's settings where no crowd answers (one teacher, no team): they never reach
    the run, so a default changed since it was saved neither changes nor stops it."""
    return crowd_settings_unread_by(config.teacher, config.annotators)


def crowd_settings_unread_by(teacher: str, annotators: str) -> frozenset[str]:
    """`unread_crowd_settings` from a saved config's teacher and annotators."""
    if parse_teacher(teacher).kind == "crowd" or annotators:
        return frozenset()
    return frozenset(CROWD_SETTINGS)


def with_unread_crowd_defaults(config: TrainConfig) -> TrainConfig:
    """`config` with the crowd's settings it never reads at today's defaults (a run saved
    under older defaults resumes under today's rules)."""
    unread = unread_crowd_settings(config)
    defaults: dict[str, Any] = {f.name: f.default for f in fields(config) if f.name in unread}
    return replace(config, **defaults)


def check_crowd(config: TrainConfig) -> None:
    """The crowd's settings act on a crowd's answers only."""
    kind = config.teacher_spec.kind
    if config.annotators:
        if not config.reward.asks:
            raise SettingError(
                f"{setting('annotators')} names a team that answers questions; "
                f"{setting('reward')} '{config.reward}' asks none: leave one of them out"
            )
        if kind != "human":
            raise SettingError(
                f"{setting('annotators')} names a team at the labelling page; "
                f"{setting('teacher')} '{config.teacher}' is scripted: use `seqrank label "
                "online --annotators ...`, or a simulated crowd (crowd:oracle+noisy)"
            )
        check_annotator_names(config.annotators, setting("annotators"))
        if config.closure_checks:  # (the page asks others the asked pair itself)
            raise SettingError(
                f"{setting('closure_checks')} {config.closure_checks}: the labelling page asks "
                "others about the pair a member answered, not the pairs their chain inferred: "
                "leave it out (a simulated crowd takes it)"
            )
    if not unread_crowd_settings(config):
        return
    crowd_only = [f for f in fields(config) if f.name in CROWD_SETTINGS]
    given = [f.name for f in crowd_only if getattr(config, f.name) != f.default]
    if given:
        names = " and ".join(setting(name) for name in given)
        act = "act" if len(given) > 1 else "acts"
        team = (
            f"name a team with {setting('annotators')}"
            if kind == "human"
            else "use a crowd (crowd:oracle+mistake+noisy)"
        )
        raise SettingError(
            f"{names} {act} on a crowd's answers; {setting('teacher')} '{config.teacher}' is "
            f"one teacher: leave them out, or {team}"
        )


ANNOTATOR_NAME = re.compile(r"[A-Za-z][A-Za-z0-9._-]{0,39}")  # ASCII only: no look-alikes
NAME_RULE = (
    "use ASCII letters, digits, '-', '_' and '.', starting with a letter, at most 40 "
    "characters; 'operator' is reserved"
)


def check_annotator_names(names: str, option: str) -> tuple[str, ...]:
    """A team's names, comma-separated: each ASCII letters, digits, '-', '_' and '.',
    starting with a letter (so no two names look alike: `аlice` with a Cyrillic а is
    refused), at most 40 characters, not `operator` (the operator's page), each once
    whatever its case."""
    shown = ascii(names)  # a look-alike shows as the escape it is: '\u0430lice'
    team = tuple(name.strip() for name in names.split(","))
    seen: dict[str, str] = {}
    for name in team:
        if not ANNOTATOR_NAME.fullmatch(name):
            raise SettingError(
                f"{option} {shown}: {name!a} is not a name{_outside(name)}; {NAME_RULE} "
                "(comma-separated: alice,bob,carol)"
            )
        if name.lower() == "operator":
            raise SettingError(
                f"{option} {shown}: {name!r} is reserved for the operator's page; give the "
                "annotator another name"
            )
        earlier = seen.get(name.lower())
        if earlier is not None:
            spelled = "" if earlier == name else f" (as {earlier}: case is not told apart)"
            raise SettingError(f"{option} {shown}: {name} given twice{spelled}; names are unique")
        seen[name.lower()] = name
    return team


def _outside(name: str) -> str:
    """Which character of a refused name is outside the accepted set, if one is."""
    for character in name:
        if not (character.isascii() and (character.isalnum() or character in "._-")):
            label = unicodedata.name(character, f"U+{ord(character):04X}")
            return f": {character!a} ({label}) is not accepted"
    return ""


def check_learner(config: TrainConfig) -> None:
    """The reward learners' settings that depend on each other (SURF's crop on SURF's
    runs only: a plain run of short segments is no business of its default)."""
    if config.reward_learner == "surf" and config.surf_crop >= config.segment_length:
        raise SettingError(
            f"{setting('surf_crop')} {config.surf_crop} must be smaller than "
            f"{setting('segment_length')} {config.segment_length}: a crop keeps at least one "
            f"step; accepted: 0 to {config.segment_length - 1}"
        )
    if config.rime_beta_min > config.rime_beta_max:
        raise SettingError(
            f"{setting('rime_beta_min')} {config.rime_beta_min} exceeds "
            f"{setting('rime_beta_max')} {config.rime_beta_max}: the uncertainty weight "
            "decays from max to min"
        )
    if config.rime_tau_upper >= 0.5:
        raise SettingError(
            f"{setting('rime_tau_upper')} must be below 0.5, got {config.rime_tau_upper}: "
            "RIME flips a label the model gives less than this probability"
        )
    if config.reward_learner == "rime" and config.rime_min_epochs > config.reward_epochs:
        raise SettingError(
            f"{setting('rime_min_epochs')} {config.rime_min_epochs} exceeds "
            f"{setting('reward_epochs')} {config.reward_epochs}, the most a fit runs; "
            f"accepted: 1 to {config.reward_epochs}"
        )


# what the clips of a session show, in session order (the study's instructions: first
# low-performing trajectories, then trajectories of varying performance)
FINETUNE_PARTS = ("low", "varied")


def check_fine_tuning(config: TrainConfig) -> None:
    parts = [p for p in config.parts.split(",") if p]
    if any(p not in FINETUNE_PARTS for p in parts):
        raise SettingError(
            f"{setting('parts')} {config.parts!r}: give a comma-separated list of "
            f"{', '.join(FINETUNE_PARTS)}"
        )
    if not config.start_from:
        return
    source = Path(config.start_from)
    if not (source / "checkpoint.pt").is_file() or not (source / "config.json").is_file():
        raise SettingError(
            f"{setting('start_from')} {config.start_from!r}: not a run directory with a "
            "checkpoint (config.json and checkpoint.pt)"
        )
    saved = json.loads((source / "config.json").read_text())
    if canonical_task(saved["task"]) != canonical_task(config.task):
        raise SettingError(
            f"{setting('start_from')} {config.start_from!r} trained {saved['task']!r}, not "
            f"{config.task!r}"
        )
    for name in ("hidden", "layers", "reward_hidden", "reward_layers", "reward_ensemble"):
        if saved.get(name) != getattr(config, name):
            raise SettingError(
                f"{setting('start_from')} {config.start_from!r} has {setting(name)} "
                f"{saved.get(name)!r}, this run {getattr(config, name)!r}: a run starts from "
                "one of the same task and sizes"
            )


def check_budget(config: TrainConfig) -> None:
    """Every session of the feedback budget falls within the run's steps."""
    last_session = config.first_session_step + (config.sessions - 1) * config.feedback_frequency
    if last_session >= config.steps:
        raise SettingError(
            f"impossible budget: {config.sessions} sessions of {config.reward_batch} questions "
            f"every {config.feedback_frequency} steps from step {config.first_session_step} "
            f"end at step {last_session}, but the run has only {config.steps} steps; raise "
            f"{setting('steps')} or {setting('reward_batch')}, or lower "
            f"{setting('max_feedback')} or {setting('feedback_frequency')}"
        )


def check_baseline(config: TrainConfig) -> None:
    """A baseline run (`reward` true or none) asks no questions."""
    if config.backbone != Backbone.PEBBLE:
        raise SettingError(
            f"{setting('backbone')} '{config.backbone}' learns its reward from feedback; "
            f"{setting('reward')} '{config.reward}' asks for none: use {setting('backbone')} "
            "pebble"
        )
    if config.teacher_spec.kind == "human" and config.record_states:  # `seqrank label`
        raise SettingError(
            f"the labelling page asks a person questions; {setting('reward')} "
            f"'{config.reward}' asks none: leave {setting('reward')} out"
        )
    if config.teacher_spec.kind != "scripted":
        raise SettingError(
            f"{setting('teacher')} '{config.teacher}' answers questions; {setting('reward')} "
            f"'{config.reward}' asks none: leave {setting('teacher')} out"
        )
    given = [name for name, default in LEARNING_FROM_ANSWERS if getattr(config, name) != default]
    if given:
        names = " and ".join(setting(name) for name in given)
        act, them = ("act", "them") if len(given) > 1 else ("acts", "it")
        raise SettingError(
            f"{names} {act} on what answers teach the reward model; {setting('reward')} "
            f"'{config.reward}' asks for none: leave {them} out"
        )


# the options of learning from answers, and their defaults (a baseline keeps them): the
# reward learner and the augmentation act on answers; RIME's warm start prepares the
# reward model for them
LEARNING_FROM_ANSWERS = (("reward_learner", "plain"), ("augment", "full"), ("warm_start", 0))


# the settings a replayed label file fixes, as its messages name them
RECORDED = {
    "task": "task",
    "scheme": "scheme",
    "segment_length": "segment length",
    "reward_batch": "questions per session",
}


def replayed(teacher: Any) -> Recorded | None:
    """What the label file of a `replay:FILE` teacher fixes (None for other teachers); a
    file that is missing or does not parse is a ValueError naming it."""
    if not isinstance(teacher, str) or parse_teacher(teacher).kind != "replay":
        return None
    from seqrank.feedback.replay import ReplaySource  # (with the reward model: only here)

    file = parse_teacher(teacher).replay_file
    assert file is not None
    return ReplaySource.from_file(file).recorded()


def recorded_values(recorded: Recorded, budget: Any) -> dict[str, Any]:
    """The settings a replaying run takes from its file where the user gives none: all its
    answers, in sessions of the recorded size (cut to a smaller `budget` given)."""
    per_session = recorded.session_questions
    if isinstance(budget, int) and 0 < budget < per_session:
        per_session = budget  # one session, cut short like the run's last
    values = {
        "scheme": recorded.scheme,
        "segment_length": recorded.segment_length,
        "reward_batch": per_session,
        "max_feedback": recorded.answers,
    }
    return values if recorded.task is None else {"task": recorded.task, **values}


def check_recorded(config: TrainConfig, recorded: Recorded, given: Collection[str]) -> None:
    """A replaying run's settings given otherwise than its label file recorded them (the
    run would use the file's and record the given ones), a budget beyond its answers, and
    a selection of new segments (the file's were chosen when it was recorded)."""
    taken = recorded_values(recorded, config.max_feedback)
    for name in (n for n in RECORDED if n in given and n in taken):
        if not _same(name, getattr(config, name), taken[name]):
            raise SettingError(
                f"{setting(name)} {getattr(config, name)} conflicts with the replay file's "
                f"{RECORDED[name]} {taken[name]} ({recorded.file}); leave {setting(name)} out "
                "to take the file's"
            )
    if config.max_feedback > recorded.answers:
        raise SettingError(
            f"{setting('max_feedback')} {config.max_feedback} exceeds the {recorded.answers} "
            f"answers of the replay file ({recorded.file}); accepted: 1 to {recorded.answers}, "
            f"or leave {setting('max_feedback')} out to replay them all"
        )
    if config.selection is not Selection.UNIFORM:
        raise SettingError(
            f"{setting('selection')} {config.selection} picks new segments to ask about; "
            f"the replay file's were picked when it was recorded ({recorded.file}): leave "
            f"{setting('selection')} out"
        )


def _same(name: str, value: Any, recorded: Any) -> bool:
    if name == "task":
        return same_task(value, recorded)
    return bool(value == recorded)
