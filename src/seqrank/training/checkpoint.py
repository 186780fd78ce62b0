"""What a checkpoint holds: every part's state, the counters and both random streams, so
a resumed run reproduces an uninterrupted one on the same machine. Nothing in it depends
on the path (reference or fast) that wrote it."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
import torch

from seqrank.agents.protocol import Agent
from seqrank.buffer import ReplayBuffer
from seqrank.episodes import EpisodeStore
from seqrank.feedback.labels import LabelStore
from seqrank.reward.model import RewardModel
from seqrank.training.collect import Collector
from seqrank.training.evaluator import Evaluations
from seqrank.training.pretrain import EntropyPretraining
from seqrank.training.reward_phase import RewardLearning
from seqrank.training.runs import RunDir
from seqrank.training.runtime import Runtime
from seqrank.training.state import Counters


class Checkpointed(Protocol):
    """The parts of a run whose state a checkpoint holds (a `Trainer` has them)."""

    counters: Counters
    run_dir: RunDir
    runtime: Runtime
    agent: Agent
    reward_model: RewardModel
    reward: RewardLearning
    replay: ReplayBuffer
    episodes: EpisodeStore
    labels: LabelStore
    pretraining: EntropyPretraining
    rng: np.random.Generator
    generator: torch.Generator
    collector: Collector
    evaluations: Evaluations


def save_checkpoint(t: Checkpointed) -> None:
    c = t.counters
    c.last_checkpoint_step = c.step
    t.run_dir.save_checkpoint(
        {
            "counters": c.state_dict(),
            "agent": t.agent.state_dict(),
            "reward_model": t.reward_model.state_dict(),
            "reward_learner": t.reward.learner.state_dict(),  # e.g. RIME's epoch count
            "replay": t.replay.state_dict(),
            "episodes": t.episodes.state_dict(),
            "labels": t.labels.state_dict(),
            "entropy_stats": t.pretraining.stats.state_dict(),
            "rng": t.rng.bit_generator.state,
            "generator": t.generator.get_state(),
            **t.collector.state_dict(),
            "pending_evaluations": t.evaluations.state_dict(),
            "metrics_rows": len(t.run_dir.read_metrics()),
            "path": t.runtime.path,  # for the record: any path may resume it
        }
    )


def load_checkpoint(t: Checkpointed, state: dict[str, Any]) -> None:
    c = t.counters
    for name, value in state["counters"].items():
        if name != "extra":
            setattr(c, name, value)
    c.extra.clear()  # in place: the MRN update writes into this dict
    c.extra.update(state["counters"].get("extra", {}))
    t.agent.load_state_dict(state["agent"])
    t.reward_model.load_state_dict(state["reward_model"])
    t.reward.learner.load_state_dict(state.get("reward_learner", {}))
    t.replay.load_state_dict(state["replay"])
    t.episodes.load_state_dict(state["episodes"])
    t.labels.load_state_dict(state["labels"])
    t.pretraining.stats.load_state_dict(state["entropy_stats"])
    t.rng.bit_generator.state = state["rng"]
    t.generator.set_state(state["generator"])
    t.collector.load_state_dict(state)
    t.evaluations.resume(state.get("pending_evaluations", []))
    t.run_dir.truncate_metrics(c.step, state.get("metrics_rows"))
