"""A `PreferenceFeedback` saved and loaded: `settings.json` (the run config and the SB3
options), `feedback.pt` (every part's state, the counters, the random streams, the episode
each environment is in, the true rewards beside the replay buffer), `labels.jsonl` (the
labels in seqrank's label format) and `metrics.jsonl` (a row per session). A run saved within
an episode is refused when it would continue (`check_continuable`)."""

from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path
from typing import Any

import torch

from seqrank.config import TrainConfig
from seqrank.dirs import check_folder
from seqrank.feedback.label_file import store_lines
from seqrank.sb3.settings import FEEDBACK_SETTINGS
from seqrank.sb3.state import FeedbackState, Resumed
from seqrank.sb3.streams import capture_rng
from seqrank.sb3.tables import ReplayTable

SETTINGS, STATE, LABELS, METRICS = "settings.json", "feedback.pt", "labels.jsonl", "metrics.jsonl"


def save(state: FeedbackState, model: Any, folder: Path) -> None:
    """Write the feedback's `state` (and the random streams of SB3's `model`, if any)."""
    check_folder(folder, "feedback folder")
    folder.mkdir(parents=True, exist_ok=True)
    run, given = state.run, state.given
    settings = {"config": given.as_dict(), **state.options}
    settings["teacher_is_value"] = not _custom_teacher(state)
    settings["from_task_name"] = state.from_task_name
    (folder / SETTINGS).write_text(json.dumps(settings, indent=2, default=str) + "\n")
    saved = run.state_dict()
    # the episode in progress starts again from its seed when the run continues
    saved["episodes_started"] = [max(e.next_episode - 1, 0) for e in state.seeded]
    saved["steps_into_episodes"] = list(state.env.steps_into_episodes)
    saved["global_rng"] = capture_rng(model)
    if isinstance(state.table, ReplayTable):
        saved["true"] = state.table.true.copy()
    torch.save(saved, folder / STATE)
    header = {"task": given.task, "obs_dim": run.obs_dim, "act_dim": run.act_dim}
    header["segment_length"] = given.segment_length
    lines = store_lines(run.labels, header, "sb3", given.scheme, given.teacher)
    (folder / LABELS).write_text("".join(line + "\n" for line in lines))
    rows = "".join(json.dumps(row, default=float) + "\n" for row in state.metrics)
    (folder / METRICS).write_text(rows)


def saved_keywords(folder: Path, env: Any, options: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
    """The first argument and keywords that make the feedback saved in `folder` anew
    (`options` replace saved keywords)."""
    if not (folder / SETTINGS).is_file() or not (folder / STATE).is_file():
        raise ValueError(f"{folder} holds no saved feedback ({SETTINGS} and {STATE})")
    saved = json.loads((folder / SETTINGS).read_text())
    config = saved["config"]
    if not saved.get("teacher_is_value", True) and "teacher" not in options:
        raise ValueError(
            f"{folder} was answered by your own source: pass it again, "
            "PreferenceFeedback.load(folder, env, teacher=...)"
        )
    if env is None and not saved.get("from_task_name", True):
        raise ValueError(
            f"{folder} was made for your own environment ({config['task']}): pass it again, "
            "PreferenceFeedback.load(folder, env)"
        )
    kinds = {f.name: f.type for f in fields(TrainConfig)}
    settings = {name: config[name] for name in FEEDBACK_SETTINGS if name in config}
    settings = {name: _typed(value, kinds[name]) for name, value in settings.items()}
    keywords = {k: saved[k] for k in ("pretrain", "reset_critic", "n_envs", "wait_for_feedback")}
    keywords.update(scale=config["scale"], **settings)
    keywords.update(options)
    return (config["task"] if env is None else env), keywords


def restore(state: FeedbackState, folder: Path) -> None:
    """The saved parts, counters, episodes and metrics, into a feedback made anew."""
    saved = torch.load(folder / STATE, weights_only=False)
    state.run.load_state_dict(saved)
    for wrapper, started in zip(state.seeded, saved["episodes_started"], strict=False):
        wrapper.next_episode = started
    steps = saved.get("steps_into_episodes", [0] * len(state.seeded))
    state.resumed = Resumed(folder, saved["global_rng"], saved.get("true"), steps)
    rows = (folder / METRICS).read_text().splitlines() if (folder / METRICS).exists() else []
    state.metrics = [json.loads(row) for row in rows]


def check_continuable(resumed: Resumed) -> None:
    """A run saved within an episode is refused: it would not continue as uninterrupted
    (the episode's start would be played again)."""
    within = [(i, n) for i, n in enumerate(resumed.steps_into_episodes) if n]
    if within:
        where = ", ".join(f"environment {i} {n} steps" for i, n in within)
        raise ValueError(
            f"{resumed.folder} was saved within an episode ({where} into it): a run continues "
            "exactly only from a save at an episode end; save when every episode has just "
            "ended (learn's total_timesteps a whole number of episodes), or start a new "
            f"feedback; its labels replay with teacher='replay:{resumed.folder / LABELS}'"
        )


def _custom_teacher(state: FeedbackState) -> bool:
    from seqrank.feedback.session import ScriptedSource

    return (
        state.page is None
        and not isinstance(state.run.source, ScriptedSource)
        and (state.given.teacher_spec.kind != "replay")
    )


def _typed(value: Any, kind: Any) -> Any:
    """A saved value as its setting's type (json keeps 1.0 as 1.0, an enum as its text)."""
    return float(value) if str(kind) == "float" and isinstance(value, int) else value
