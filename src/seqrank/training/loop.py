"""The PEBBLE / MRN training loop (SPEC sections 1 and 7), divided into named phases.

Phases by step: random actions for `seed_steps`; SAC on the state-entropy reward until
`seed_steps + unsup_steps`; then the first feedback session, reward training, relabelling,
critic reset and `updates_after_reset` SAC updates; afterwards one SAC update per step and
a feedback session every `feedback_frequency` steps while budget remains. MRN replaces the
SAC update by a meta reward step plus a SAC update every `meta_update_frequency` steps.

Every episode and evaluation episode is seeded from the run seed and its index, and all
other randomness comes from one numpy and one torch generator that are checkpointed, so a
resumed CPU run reproduces an uninterrupted one exactly.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
import torch

from seqrank.agents.fast_sac import FastSAC
from seqrank.agents.mrn import PairBatch, meta_reward_step
from seqrank.agents.precision import matmul_precision
from seqrank.agents.sac import SAC, SACSettings
from seqrank.buffer import Batch, ReplayBuffer
from seqrank.config import DEVICES, PRECISIONS, TrainConfig
from seqrank.envs import canonical_task, make_env
from seqrank.episodes import Episode, EpisodeStore, Segments
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.schemes import SessionRecord
from seqrank.feedback.session import (
    FeedbackSource,
    ScriptedSource,
    SessionRequest,
    prepare_session,
    store_session,
)
from seqrank.feedback.teachers import ScriptedTeacher, teacher_preset
from seqrank.reward.entropy import RunningMeanStd, intrinsic_reward
from seqrank.reward.model import RewardModel
from seqrank.training.eval_worker import (
    BackgroundEvaluator,
    PendingEvaluation,
    host_copy,
    score_row,
)
from seqrank.training.evaluation import PolicyScore, evaluate_policy, reward_quality
from seqrank.training.runs import RunDir

Progress = Callable[[int, dict[str, Any]], None]
TRAIN_LOG_EVERY = 1_000  # steps between `train` rows of metrics.jsonl


@dataclass
class Counters:
    step: int = 0
    episode: int = 0
    sessions: int = 0
    asked: int = 0
    answered: int = 0
    inferred: int = 0
    inferred_wrong: int = 0
    last_session_step: int = 0
    last_checkpoint_step: int = 0
    evaluations: int = 0
    last_eval_return: float | None = None
    last_eval_success: float | None = None
    train_seconds: float = 0.0
    extra: dict[str, float] = field(default_factory=dict)


def resolve_path(name: str, device: torch.device, discrete: bool) -> bool:
    """True for the fast path: asked for, or `auto` on CUDA for SAC tasks."""
    if name == "auto":
        return device.type == "cuda" and not discrete
    return name == "fast"


def resolve_path_and_precision(config: TrainConfig, device: torch.device) -> tuple[bool, str]:
    """(fast path?, precision) for a run on `device`; ValueError for a precision the path
    does not offer."""
    discrete = canonical_task(config.task)[0] == "block"
    fast = resolve_path(config.path, device, discrete)
    return fast, resolve_precision(config.precision, device, fast)


def resolve_precision(name: str, device: torch.device, fast: bool) -> str:
    """`auto`: TF32 for the fast path on CUDA, fp32 everywhere else."""
    if name not in PRECISIONS:
        raise ValueError(f"unknown precision {name!r}; accepted: {', '.join(PRECISIONS)}")
    if not fast and name not in ("auto", "fp32"):
        raise ValueError(
            f"precision {name!r} needs the fast path: the reference path is strict fp32 "
            "(use --path fast, or --precision fp32)"
        )
    if name == "auto":
        return "tf32" if fast and device.type == "cuda" else "fp32"
    return name


def resolve_device(name: str) -> torch.device:
    if name not in DEVICES:
        raise ValueError(f"unknown device {name!r}; accepted: {', '.join(DEVICES)}")
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("device 'cuda' requested but no CUDA device is available; use cpu or auto")
    return torch.device(name)


def _empty_episode() -> dict[str, list[Any]]:
    return {"obs": [], "action": [], "reward": [], "states": []}


def episode_seed(run_seed: int, *path: int) -> int:
    return int(np.random.SeedSequence([run_seed, *path]).generate_state(1)[0])


def make_source(teacher: str) -> FeedbackSource:
    """The feedback source a teacher name stands for: a scripted preset or `replay:FILE`."""
    if teacher.startswith("replay:"):
        from seqrank.feedback.replay import ReplaySource

        return ReplaySource.from_file(teacher.removeprefix("replay:"))
    if teacher == "human":
        raise ValueError(
            "teacher 'human' answers on the labelling page: start the run with "
            "`seqrank label online ...` instead of `seqrank train`"
        )
    return ScriptedSource(ScriptedTeacher(teacher_preset(teacher)))


def make_agent(
    config: TrainConfig, env: Any, device: torch.device, fast: bool = False, precision: str = "fp32"
) -> Any:
    """SAC (reference or fast) for continuous control; DQN (D.1) for discrete tasks such as
    block:place."""
    if env.discrete:
        from seqrank.agents.dqn import DQN, DQNSettings, EpsilonSchedule

        dqn = DQNSettings(
            config.hidden,
            config.layers,
            config.critic_lr,
            config.discount,
            config.tau,
            config.target_update_every,
            EpsilonSchedule(random_steps=config.seed_steps),
        )
        return DQN(env.obs_dim, env.act_dim, dqn, device)
    settings = SACSettings(
        config.hidden,
        config.layers,
        config.actor_lr,
        config.critic_lr,
        config.alpha_lr,
        config.init_temperature,
        config.discount,
        config.tau,
        config.target_update_every,
    )
    if fast:
        return FastSAC(env.obs_dim, env.act_dim, settings, device, precision)
    return SAC(env.obs_dim, env.act_dim, settings, device)


def open_trainer(
    factory: Callable[[TrainConfig, RunDir], Trainer], config: TrainConfig, run: RunDir
) -> tuple[Trainer, dict[str, Any] | None]:
    """A trainer for `run`, continued from its checkpoint when it has one. A run with
    `path auto` continues on the path that wrote the checkpoint (their agents' weights are
    laid out differently), whatever device it resumes on."""
    state = run.load_checkpoint()
    if state is not None and config.path == "auto" and "path" in state:
        config = replace(config, path=state["path"])
    trainer = factory(config, run)
    if state is not None:
        trainer.load_checkpoint(state)
    return trainer, state


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
        self.wait_for_feedback = wait_for_feedback
        self._pending: tuple[SessionRequest, Future[tuple[Segments, SessionRecord]]] | None = None
        self._background: ThreadPoolExecutor | None = None
        self.device = resolve_device(config.device)
        torch.manual_seed(config.seed)
        self.env = make_env(config.task, config.seed)
        self.eval_env = make_env(config.task, config.seed)
        if config.first_session_step < self.env.episode_length:
            raise ValueError(
                f"the first feedback session (step {config.first_session_step}) comes before "
                f"the first complete episode ({self.env.episode_length} steps); raise "
                "--seed-steps or --unsup-steps"
            )
        obs_dim, act_dim = self.env.obs_dim, self.env.act_dim
        self.fast, self.precision = resolve_path_and_precision(config, self.device)
        self.agent = make_agent(config, self.env, self.device, self.fast, self.precision)
        self.reward_model = RewardModel(
            config.reward_ensemble,
            obs_dim + act_dim,
            config.reward_hidden,
            config.reward_layers,
            config.reward_lr,
            self.device,
        )
        # the reference keeps the buffer on the host and copies each batch to the device
        storage = self.device if self.fast else torch.device("cpu")
        self.replay = ReplayBuffer(config.steps, obs_dim, act_dim, self.device, storage)
        self.episodes = EpisodeStore(config.episodes_kept)
        self.labels = LabelStore()
        self.source = source if source is not None else make_source(config.teacher)
        self.source.check_compatible(config, obs_dim, act_dim)
        self.rng = np.random.default_rng(np.random.SeedSequence(config.seed))
        self.generator = torch.Generator().manual_seed(config.seed)
        self.entropy_stats = RunningMeanStd()
        self.counters = Counters()
        self._current = _empty_episode()
        # fast path: the next action is computed before this step's update is launched, so
        # the simulator steps on the host while the GPU updates (one update stale)
        self._next_action: np.ndarray | None = None
        self._evaluator: BackgroundEvaluator | None = None  # fast path: a separate process
        self._resubmit: list[dict[str, Any]] = []
        self._started = time.perf_counter()

    # ---- the loop -------------------------------------------------------------------
    def train(self) -> dict[str, Any]:
        try:
            with matmul_precision(self.precision):
                return self._train()
        finally:
            if self._evaluator is not None:
                self._evaluator.close()
                self._evaluator = None

    def _train(self) -> dict[str, Any]:
        config, c = self.config, self.counters
        if self._resubmit:
            self._background_evaluator()
        obs, info = self.env.reset(seed=episode_seed(config.seed, 0, c.episode))
        context = info.get("task_index")
        tick = time.perf_counter()
        while c.step < config.steps:
            action = self._act(obs) if self._next_action is None else self._next_action
            if config.record_states:
                self._current["states"].append(self.env.get_state())
            next_obs, reward, terminated, truncated, info = self.env.step(action)
            self._store(obs, action, float(reward), next_obs, terminated)
            obs, c.step = next_obs, c.step + 1
            episode_over = terminated or truncated
            if episode_over:
                self._end_episode(context)
                obs, info = self.env.reset(seed=episode_seed(config.seed, 0, c.episode))
                context = info.get("task_index")
            if self.fast:
                self._next_action = self._act(obs) if c.step < config.steps else None
            self._learn()
            if c.step % TRAIN_LOG_EVERY == 0 and self.agent.last_metrics:
                self._log_training()
            if c.step % config.eval_every == 0 or c.step == config.steps:
                self._evaluate()
            self._collect_evaluations(everything=c.step == config.steps)
            now = time.perf_counter()
            c.train_seconds, tick = c.train_seconds + now - tick, now
            if self.progress is not None and (c.step % 100 == 0 or c.step == config.steps):
                self.progress(c.step, self._live())
            if episode_over and c.step - c.last_checkpoint_step >= config.checkpoint_every:
                self.save_checkpoint()
        return self._summary()

    # ---- phases ---------------------------------------------------------------------
    def _act(self, obs: np.ndarray) -> np.ndarray:
        if self.counters.step < self.config.seed_steps:
            return self.rng.uniform(-1.0, 1.0, self.env.act_dim).astype(np.float32)
        action: np.ndarray = self.agent.act(obs, False, self.generator)
        return action

    def _store(
        self,
        obs: np.ndarray,
        action: np.ndarray,
        reward: float,
        next_obs: np.ndarray,
        terminated: bool,
    ) -> None:
        action = self.env.canonical_action(action)
        trained = self.counters.sessions > 0
        if self.fast:  # the learned reward is computed on the device, nothing read back
            reward_fn = self.reward_model.reward if trained else None
            self.replay.add_staged(obs, action, reward, next_obs, terminated, reward_fn)
        else:  # the reference asks the reward model on the host at every step
            learned = self.reward_model.reward_numpy(obs, action) if trained else 0.0
            self.replay.add(obs, action, reward, learned, next_obs, terminated)
        for key, value in (("obs", obs), ("action", action), ("reward", reward)):
            self._current[key].append(value)

    def _end_episode(self, context: int | None) -> None:
        cur = self._current
        self.episodes.add(
            Episode(
                np.asarray(cur["obs"], np.float32),
                np.asarray(cur["action"], np.float32),
                np.asarray(cur["reward"], np.float64),
                context,
                np.asarray(cur["states"]) if cur["states"] else None,
            )
        )
        self._current = _empty_episode()
        self.counters.episode += 1

    def _learn(self) -> None:
        config, c = self.config, self.counters
        if c.step < config.seed_steps:
            return
        if c.step < config.first_session_step:
            self._unsupervised_update()
            return
        if self._pending is not None and self._pending[1].done():
            request, answered = self._pending
            self._pending = None
            self._finish_feedback(request, *answered.result())
        budget_left = c.asked < config.max_feedback and self.source.has_session(c.sessions)
        if self._pending is None and (
            c.sessions == 0
            or (budget_left and c.step - c.last_session_step >= config.feedback_frequency)
        ):
            self._feedback()
        meta_step = c.step % config.meta_update_frequency == 0 and len(self.labels) > 0
        if config.backbone == "mrn" and budget_left and meta_step:
            self._meta_update()
        elif self.fast:
            self.agent.update_from_buffer(self.replay, config.batch, self.generator)
        else:
            self.agent.update(self.replay.sample(config.batch, self.generator), self.generator)

    def _unsupervised_update(self) -> None:
        batch = self.replay.sample(self.config.batch, self.generator)
        stored = self.replay.obs[: len(self.replay)].to(self.device)
        reward = intrinsic_reward(batch.obs, stored, self.config.knn_k, self.entropy_stats)
        batch = Batch(batch.obs, batch.action, reward, batch.next_obs, batch.not_done)
        self.agent.update(batch, self.generator)

    def _feedback(self) -> None:
        config, c = self.config, self.counters
        first = c.sessions == 0
        questions = min(config.reward_batch, config.max_feedback - c.asked)
        margin_returns = self.episodes.recent_returns(10)
        margin = float(margin_returns.mean()) * config.segment_length / self.env.episode_length
        request = prepare_session(
            config,
            questions,
            self.episodes,
            self.reward_model,
            c.sessions,
            self.rng,
            informative=not first,
            margin=margin,
        )
        if first or self.wait_for_feedback:
            self._finish_feedback(request, *self.source.ask_session(request))
            return
        if self._background is None:
            self._background = ThreadPoolExecutor(1, thread_name_prefix="feedback")
        self._pending = (request, self._background.submit(self.source.ask_session, request))
        c.last_session_step = c.step

    def _finish_feedback(
        self, request: SessionRequest, segments: Segments, record: SessionRecord
    ) -> None:
        config, c = self.config, self.counters
        first = request.session == 0
        outcome = store_session(segments, record, self.labels, request.session)
        stats = outcome.stats
        c.sessions += 1
        c.asked += stats.asked
        c.answered += stats.answered
        c.inferred += stats.inferred
        c.inferred_wrong += stats.inferred_wrong or 0
        c.last_session_step = c.step
        # every answer so far may be a skip (B-Pref's skip teacher on all-negative returns):
        # then there is nothing to fit yet, and the reward model stays as it is
        result = self._train_reward() if len(self.labels) else None
        self._relabel()
        if first:
            self.agent.reset_critic()
            for _ in range(config.updates_after_reset):
                self.agent.update(self.replay.sample(config.batch, self.generator), self.generator)
        self.run_dir.append_metrics(
            {
                "step": c.step,
                "kind": "feedback",
                "session": c.sessions,
                "questions": stats.asked,
                "answered": stats.answered,
                "equal": stats.equal,
                "skipped": stats.skipped,
                "inferred": stats.inferred,
                "inferred_wrong": stats.inferred_wrong,
                "asked_wrong": stats.asked_wrong,
                "pairs_per_question": stats.pairs_per_question,
                "max_degree": stats.max_degree,
                "mean_degree": stats.mean_degree,
                "cyclic_components": stats.cyclic_components,
                "total_asked": c.asked,
                "total_inferred": c.inferred,
                "total_inferred_wrong": c.inferred_wrong,
                "total_pairs": len(self.labels),
                "reward_epochs": result.epochs if result else 0,
                "reward_loss": result.loss if result else None,
                "reward_train_accuracy": result.accuracy if result else None,
                **self._reward_quality(c.sessions),
            }
        )

    def _train_reward(self) -> Any:
        config = self.config
        segments, first, second, labels = self.labels.tensors(self.device)
        return self.reward_model.train(
            segments,
            first,
            second,
            labels,
            config.reward_epochs,
            config.reward_minibatch,
            config.reward_stop_accuracy,
            self.generator,
            sync_every_step=not self.fast,
        )

    def _meta_update(self) -> None:
        config = self.config
        batch = self.replay.sample(config.batch, self.generator)
        segments, first, second, labels = self.labels.tensors(self.device, last=config.reward_batch)
        obs_dim = self.env.obs_dim
        a, b = segments[first][:, 0], segments[second][:, 0]
        pairs = PairBatch(a[:, :obs_dim], a[:, obs_dim:], b[:, :obs_dim], b[:, obs_dim:], labels)
        loss = meta_reward_step(
            self.agent, self.reward_model, batch, pairs, self.generator, config.meta_loss_weight
        )
        self.counters.extra["meta_outer_loss"] = loss
        with torch.no_grad():
            reward = self.reward_model.reward(batch.obs, batch.action)
        self.agent.update(
            Batch(batch.obs, batch.action, reward, batch.next_obs, batch.not_done), self.generator
        )
        self._relabel()

    def _relabel(self) -> None:
        self.replay.relabel(self.reward_model.reward, chunk=65_536 if self.fast else 8_192)

    def _reward_quality(self, session: int) -> dict[str, float]:
        config = self.config
        rng = np.random.default_rng([config.seed, 2, session])
        return reward_quality(
            self.reward_model,
            self.episodes,
            self.replay,
            config.heldout_pairs,
            config.segment_length,
            rng,
        )

    def _evaluate(self) -> None:
        """Evaluate now (reference path), or hand the actor to the evaluation process and
        log the scores `eval_every / 2` steps later (fast path)."""
        config, c = self.config, self.counters
        seeds = [
            episode_seed(config.seed, 1, c.evaluations, i) for i in range(config.eval_episodes)
        ]
        c.evaluations += 1
        context = {
            "total_asked": c.asked,
            "total_inferred": c.inferred,
            **self.agent.eval_metrics(),
            "steps_per_second": c.step / max(c.train_seconds, 1e-9),
            "wall_seconds": c.train_seconds,
        }
        if not self.fast:
            score = evaluate_policy(self.agent, self.eval_env, seeds, self.generator)
            self._log_evaluation(c.step, score, context)
            return
        collect_at = c.step + max(config.eval_every // 2, 1)
        actor = host_copy(self.agent.actor)
        self._background_evaluator().submit(
            PendingEvaluation(c.step, collect_at, context, seeds, actor)
        )

    def _background_evaluator(self) -> BackgroundEvaluator:
        if self._evaluator is None:
            config, env = self.config, self.env
            self._evaluator = BackgroundEvaluator(
                config.task, config.seed, env.obs_dim, env.act_dim, config.hidden, config.layers
            )
            for state in self._resubmit:  # pending when the checkpoint was written
                self._evaluator.submit(PendingEvaluation(**state))
            self._resubmit = []
        return self._evaluator

    def _collect_evaluations(self, everything: bool = False) -> None:
        if self._evaluator is not None:
            for pending, score in self._evaluator.due(self.counters.step, everything):
                self._log_evaluation(pending.step, score, pending.row)

    def _log_evaluation(self, step: int, score: PolicyScore, context: dict[str, Any]) -> None:
        c = self.counters
        row = score_row(score)
        c.last_eval_return, c.last_eval_success = row["eval_return"], row["eval_success_rate"]
        self.run_dir.append_metrics({"step": step, "kind": "eval", **row, **context})

    def _log_training(self) -> None:
        c = self.counters
        phase = "pretrain" if c.step < self.config.first_session_step else "preference"
        row: dict[str, Any] = {"step": c.step, "kind": "train", "phase": phase}
        row.update(self.agent.last_metrics)
        if phase == "pretrain":
            row["intrinsic_reward_std"] = self.entropy_stats.std
        row.update(c.extra)
        self.run_dir.append_metrics(row)

    def _live(self) -> dict[str, Any]:
        c = self.counters
        return {
            "eval_return": c.last_eval_return,
            "asked": c.asked,
            "inferred": c.inferred,
            "sessions": c.sessions,
            "sps": c.step / max(c.train_seconds, 1e-9),
        }

    def _summary(self) -> dict[str, Any]:
        c = self.counters
        evals = [r for r in self.run_dir.read_metrics() if r["kind"] == "eval"]
        summary = {
            "task": self.config.task,
            "scheme": self.config.scheme,
            "teacher": self.config.teacher,
            "backbone": self.config.backbone,
            "steps": c.step,
            "final_eval_return": c.last_eval_return,
            "final_eval_success_rate": c.last_eval_success,
            "best_eval_return": max((r["eval_return"] for r in evals), default=None),
            "sessions": c.sessions,
            "asked": c.asked,
            "answered": c.answered,
            "inferred": c.inferred,
            "inferred_wrong": c.inferred_wrong,
            "wall_seconds": c.train_seconds,
            "steps_per_second": c.step / max(c.train_seconds, 1e-9),
            "eval_curve": [(r["step"], r["eval_return"]) for r in evals],
        }
        self.run_dir.write_summary(summary)
        return summary

    # ---- checkpoints ----------------------------------------------------------------
    def save_checkpoint(self) -> None:
        c = self.counters
        c.last_checkpoint_step = c.step
        self.run_dir.save_checkpoint(
            {
                "counters": {f.name: getattr(c, f.name) for f in fields(Counters)},
                "agent": self.agent.state_dict(),
                "reward_model": self.reward_model.state_dict(),
                "replay": self.replay.state_dict(),
                "episodes": self.episodes.state_dict(),
                "labels": self.labels.state_dict(),
                "entropy_stats": self.entropy_stats.state_dict(),
                "rng": self.rng.bit_generator.state,
                "generator": self.generator.get_state(),
                "next_action": self._next_action,
                "pending_evaluations": self._evaluator.state_dict() if self._evaluator else [],
                "metrics_rows": len(self.run_dir.read_metrics()),
                "path": "fast" if self.fast else "reference",
            }
        )

    def load_checkpoint(self, state: dict[str, Any]) -> None:
        saved = state.get("path", "reference")
        if saved != ("fast" if self.fast else "reference"):
            raise ValueError(
                f"the checkpoint was written by the {saved} path; this run is set to the other "
                f"one (path {self.config.path!r}): resume it with its own path"
            )
        self.counters = Counters(**state["counters"])
        self.agent.load_state_dict(state["agent"])
        self.reward_model.load_state_dict(state["reward_model"])
        self.replay.load_state_dict(state["replay"])
        self.episodes.load_state_dict(state["episodes"])
        self.labels.load_state_dict(state["labels"])
        self.entropy_stats.load_state_dict(state["entropy_stats"])
        self.rng.bit_generator.state = state["rng"]
        self.generator.set_state(state["generator"])
        self._next_action = state.get("next_action")
        self._resubmit = state.get("pending_evaluations", [])
        self.run_dir.truncate_metrics(self.counters.step, state.get("metrics_rows"))
