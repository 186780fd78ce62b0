"""A training run's parts, assembled from its config; `Trainer.train()` runs the loop."""

from __future__ import annotations

import contextlib
import os
import threading
from pathlib import Path
from typing import Any

import numpy as np
import torch

from seqrank.agents.sac.precision import matmul_precision
from seqrank.buffer import ReplayBuffer
from seqrank.choices import RewardSignal
from seqrank.config import TrainConfig
from seqrank.envs import SimEnv, make_env
from seqrank.episodes import EpisodeStore
from seqrank.errors import SettingError, setting
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.session import FeedbackSource
from seqrank.training.agent_factory import make_agent
from seqrank.training.backbones import BACKBONES, UpdateParts
from seqrank.training.checkpoint import load_checkpoint, save_checkpoint
from seqrank.training.collect import Collector
from seqrank.training.cpu_path import UpdateShape, torch_threads, training_threads
from seqrank.training.evaluator import (
    ActorShape,
    BackgroundEvaluations,
    Evaluations,
    InlineEvaluations,
)
from seqrank.training.feedback_parts import (
    make_reward_learning,
    make_reward_model,
    make_sessions,
    teacher_source,
)
from seqrank.training.finetune import refill_for_part, start_from
from seqrank.training.loop import PhaseTimer, Progress, run_loop
from seqrank.training.pretrain import EntropyPretraining
from seqrank.training.reward_phase import RewardLearning
from seqrank.training.runs import RunDir
from seqrank.training.runtime import Runtime, resolve_runtime
from seqrank.training.state import Counters


def _untimed(name: str) -> contextlib.AbstractContextManager[None]:
    return contextlib.nullcontext()


class Trainer:
    def __init__(
        self,
        config: TrainConfig,
        run: RunDir,
        progress: Progress | None = None,
        source: FeedbackSource | None = None,
        wait_for_feedback: bool = True,
    ):
        """`wait_for_feedback=False` keeps training while a session after the first is being
        answered (a person at the labelling page); its labels count once it is complete."""
        self.config, self.run_dir, self.progress = config, run, progress
        # a public hook around the `feedback_session` and `evaluation` phases (the benchmark
        # times them with it)
        self.phase_timer: PhaseTimer = _untimed
        torch.manual_seed(config.seed)
        self.env = make_env(config.task, config.seed)
        self.eval_env = make_env(config.task, config.seed)
        self.start_state = (
            RunDir.open(Path(config.start_from)).load_checkpoint() if config.start_from else None
        )
        kept = 0 if self.start_state is None else int(self.start_state["replay"]["size"])
        self.runtime = runtime = check_fits(config, self.env, kept)
        self.fast, device = runtime.fast, runtime.device
        obs_dim, act_dim = self.env.obs_dim, self.env.act_dim
        storage = device if runtime.fast else torch.device("cpu")
        self.agent = make_agent(config, self.env, runtime)
        self.reward_model = make_reward_model(config, obs_dim + act_dim, device)
        train_on = "true_reward" if config.reward is RewardSignal.TRUE else "reward"
        self.replay = ReplayBuffer(kept + config.steps, obs_dim, act_dim, device, storage, train_on)
        self.episodes = EpisodeStore(config.episodes_kept)
        self.labels = LabelStore(config.crowd_weighting.value)
        self.source = source if source is not None else teacher_source(config)
        self.source.check_compatible(config.task, obs_dim, act_dim)
        self.rng = np.random.default_rng(np.random.SeedSequence(config.seed))
        self.generator = torch.Generator().manual_seed(config.seed)
        self.counters = Counters()
        # set (by a signal handler, say) to stop at the next episode end with a checkpoint
        self.stop_requested = threading.Event()
        self._assemble_phases(wait_for_feedback)
        if self.start_state is not None:  # (the run's own checkpoint, if any, comes after)
            start_from(self.start_state, self.agent, self.reward_model, self.replay, self.episodes)
            self.start_state = None  # its replay buffer is large

    def _assemble_phases(self, wait_for_feedback: bool) -> None:
        config, runtime, env = self.config, self.runtime, self.env
        self.collector = Collector(
            env,
            self.agent,
            self.replay,
            self.episodes,
            bool(config.record_states),
            config.seed_steps,
            self.rng,
            self.generator,
            lookahead=runtime.fast,
            total_steps=config.steps,
        )
        self.pretraining = EntropyPretraining(
            self.agent,
            self.replay,
            config.batch,
            config.knn_k,
            runtime.device,
            self.generator,
            warm_start=self.reward_model if config.warm_start else None,
        )
        self.sessions = make_sessions(
            config,
            self.source,
            self.episodes,
            self.reward_model,
            self.rng,
            self.labels,
            env.episode_length,
            wait_for_feedback,
        )
        study_parts = tuple(p for p in config.parts.split(",") if p)
        if study_parts:  # before each session: episodes of the study part's skill levels
            self.sessions.before_session = lambda k: refill_for_part(
                self.env, self.agent, self.episodes, config.seed, study_parts, k
            )
        self.reward = self._reward_learning()
        parts = UpdateParts(
            self.agent,
            self.replay,
            self.reward_model,
            self.labels,
            self.reward.relabel,
            self.counters.extra.__setitem__,
            env.obs_dim,
            self.generator,
            env.episode_length,
        )
        self.update = BACKBONES[config.backbone](config, parts)
        self.evaluations = self._evaluations()

    def _reward_learning(self) -> RewardLearning:
        return make_reward_learning(
            self.config,
            self.reward_model,
            self.labels,
            self.replay,
            self.episodes,
            self.generator,
            self.runtime.fast,
        )

    def _evaluations(self) -> Evaluations:
        c = self.config
        shape = ActorShape(c.task, c.seed, self.env.obs_dim, self.env.act_dim, c.hidden, c.layers)
        actor = getattr(self.agent, "actor", None)
        if self.runtime.fast and actor is not None:
            return BackgroundEvaluations(actor, shape)
        return InlineEvaluations(self.agent, self.eval_env, self.generator, shape)

    @property
    def threads(self) -> int:
        """Torch threads the run trains with (`cpu_path.training_threads`)."""
        cpu = self.runtime.device.type == "cpu"
        return training_threads(self.runtime.fast) if cpu else torch.get_num_threads()

    def train(self) -> dict[str, Any]:
        try:
            with matmul_precision(self.runtime.precision), torch_threads(self.threads):
                return run_loop(self)
        finally:
            self.evaluations.close()
            self.run_dir.close_sinks()

    def save_checkpoint(self) -> None:
        save_checkpoint(self)

    def load_checkpoint(self, state: dict[str, Any]) -> None:
        load_checkpoint(self, state)


def check_fits(config: TrainConfig, env: SimEnv, kept: int = 0) -> Runtime:
    """What can be checked only with the task's environment at hand (`--dry-run` checks it
    too): segments fit an episode, the replay buffer (`kept` steps of a fine-tuned run's
    plus the run's) fits memory; returns where and how the run trains."""
    # a fine-tuning run starts with the saved run's episodes: its first session needs none
    check_episode_fits(config, env.episode_length, env.has_terminals or bool(config.start_from))
    shape = UpdateShape(env.obs_dim, env.act_dim, config.hidden, config.layers, config.batch)
    runtime = resolve_runtime(config.device, config.path, config.precision, env.discrete, shape)
    # the reference path keeps the buffer on the host and copies each batch over
    storage = runtime.device if runtime.fast else torch.device("cpu")
    _check_replay_fits(kept + config.steps, env.obs_dim, env.act_dim, storage)
    return runtime


def check_episode_fits(config: TrainConfig, episode_length: int, has_terminals: bool) -> None:
    """Segments are cut from complete episodes, the first ones by the first session (a
    task with terminal states may end episodes sooner: its first session waits for one)."""
    if not config.reward.asks:
        return
    if config.segment_length > episode_length:
        raise SettingError(
            f"{setting('segment_length')} {config.segment_length} is longer than an episode "
            f"of {config.task} ({episode_length} steps), so no segment can be cut; accepted: "
            f"1 to {episode_length}"
        )
    if config.first_session_step < episode_length and not has_terminals:
        raise SettingError(
            f"the first feedback session (step {config.first_session_step}) comes before "
            f"the first complete episode ({episode_length} steps); raise "
            f"{setting('seed_steps')} or {setting('unsup_steps')}"
        )


def _check_replay_fits(steps: int, obs_dim: int, act_dim: int, storage: torch.device) -> None:
    """The replay buffer keeps every step of the run: it must fit where it is stored."""
    needed = steps * ReplayBuffer.row_width(obs_dim, act_dim) * 4
    if storage.type == "cuda":
        total = torch.cuda.get_device_properties(storage).total_memory
    else:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if needed > total:
        raise SettingError(
            f"{setting('steps')} {steps}: the replay buffer keeps every step, "
            f"{needed / 2**30:,.1f} GiB, more than the {total / 2**30:,.1f} GiB of memory on "
            f"{storage.type}; lower {setting('steps')}"
        )
