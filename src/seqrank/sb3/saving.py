"""A `PreferenceFeedback` saved and loaded: `settings.json` (the run config and the SB3
options), `feedback.pt` (every part's state, the counters, the random streams, the episode
each environment is in, the true rewards beside the replay buffer), `labels.jsonl` (the
labels in seqrank's label format) and `metrics.jsonl` (a row per session)."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import fields
from pathlib import Path
from typing import Any, Protocol, TypeVar

import torch

from seqrank.config import TrainConfig
from seqrank.dirs import check_folder
from seqrank.feedback.label_file import store_lines
from seqrank.sb3.envs import SeededEpisodes
from seqrank.sb3.run import FeedbackRun
from seqrank.sb3.settings import FEEDBACK_SETTINGS
from seqrank.sb3.streams import capture_rng
from seqrank.sb3.tables import EpisodeTable, ReplayTable

SETTINGS, STATE, LABELS, METRICS = "settings.json", "feedback.pt", "labels.jsonl", "metrics.jsonl"


class SavedFeedback(Protocol):
    """What is saved of a `PreferenceFeedback` and restored into a new one (this module
    sits below the callback, which it never imports)."""

    given: TrainConfig
    options: dict[str, Any]
    from_task_name: bool
    run: FeedbackRun
    seeded: list[SeededEpisodes]
    table: ReplayTable | EpisodeTable | None
    metrics: list[dict[str, Any]]
    pending: dict[str, Any]
    page: Any


Feedback = TypeVar("Feedback", bound=SavedFeedback)


def save(feedback: SavedFeedback, folder: Path) -> None:
    check_folder(folder, "feedback folder")
    folder.mkdir(parents=True, exist_ok=True)
    run, model = feedback.run, getattr(feedback, "model", None)
    settings = {"config": feedback.given.as_dict(), **feedback.options}
    settings["teacher_is_value"] = not _custom_teacher(feedback)
    settings["from_task_name"] = feedback.from_task_name
    (folder / SETTINGS).write_text(json.dumps(settings, indent=2, default=str) + "\n")
    state = run.state_dict()
    # the episode in progress starts again from its seed when the run continues
    state["episodes_started"] = [max(e.next_episode - 1, 0) for e in feedback.seeded]
    state["global_rng"] = capture_rng(model)
    if isinstance(feedback.table, ReplayTable):
        state["true"] = feedback.table.true.copy()
    torch.save(state, folder / STATE)
    header = {"task": feedback.given.task, "obs_dim": run.obs_dim, "act_dim": run.act_dim}
    header["segment_length"] = feedback.given.segment_length
    lines = store_lines(run.labels, header, "sb3", feedback.given.scheme, feedback.given.teacher)
    (folder / LABELS).write_text("".join(line + "\n" for line in lines))
    rows = "".join(json.dumps(row, default=float) + "\n" for row in feedback.metrics)
    (folder / METRICS).write_text(rows)


def load(
    make: Callable[..., Feedback], folder: Path, env: Any, options: dict[str, Any]
) -> Feedback:
    """A saved feedback folder made anew by `make` (the class) and its state restored."""
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
    feedback = make(config["task"] if env is None else env, **keywords)
    state = torch.load(folder / STATE, weights_only=False)
    feedback.run.load_state_dict(state)
    for wrapper, started in zip(feedback.seeded, state["episodes_started"], strict=False):
        wrapper.next_episode = started
    feedback.pending = {"global_rng": state["global_rng"]}
    if "true" in state:
        feedback.pending["true"] = state["true"]
    rows = (folder / METRICS).read_text().splitlines() if (folder / METRICS).exists() else []
    feedback.metrics = [json.loads(row) for row in rows]
    return feedback


def _custom_teacher(feedback: SavedFeedback) -> bool:
    from seqrank.feedback.session import ScriptedSource

    return (
        feedback.page is None
        and not isinstance(feedback.run.source, ScriptedSource)
        and (feedback.given.teacher_spec.kind != "replay")
    )


def _typed(value: Any, kind: Any) -> Any:
    """A saved value as its setting's type (json keeps 1.0 as 1.0, an enum as its text)."""
    return float(value) if str(kind) == "float" and isinstance(value, int) else value
