"""`PreferenceFeedback`: seqrank's feedback sessions for any Stable-Baselines3 agent.

It is an SB3 callback and owns the agent's environment (`feedback.env`). After each step
the true reward is kept aside; at the end of each rollout (every step for SAC and TD3) a
session is asked when one is due, by the same code as seqrank's loop
(`training.feedback_phase`): answered, augmented, stored, the reward refitted, the replay
buffer relabelled (off-policy agents), and after the first session the critic reset.
Before the first session an off-policy agent pre-trains on the state-entropy reward.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

import seqrank.sb3.agents as agents
import seqrank.sb3.saving as saving
from seqrank.config import TrainConfig
from seqrank.errors import SettingError, setting
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.session import FeedbackSource
from seqrank.sb3.build import describe_task, make_teacher, task_names
from seqrank.sb3.envs import PreferenceVecEnv, SeededEpisodes, reward_batch, task_vec_env
from seqrank.sb3.replay import EntropyReward, PreferenceReplayBuffer
from seqrank.sb3.run import FeedbackRun
from seqrank.sb3.settings import (
    check_page_keywords,
    feedback_config,
    pebble_default,
    sb3_options,
    without_pretraining,
)
from seqrank.sb3.state import FeedbackState
from seqrank.sb3.streams import restore_rng
from seqrank.sb3.tables import EpisodeTable, ReplayTable
from seqrank.training.feedback_phase import feedback_step, learn_from_session
from seqrank.training.runtime import resolve_device
from seqrank.training.sessions import AnsweredSession
from seqrank.training.sinks import scalars
from seqrank.training.trainer import check_episode_fits


class PreferenceFeedback(BaseCallback):
    """Preferences for any Stable-Baselines3 agent: an SB3 callback that owns its env.

    Make the agent on `feedback.env` and pass `callback=feedback` to its `learn`: sessions
    are asked when due, the reward model learns from them and `feedback.env` gives the
    agent the learned reward (0 before the first session); the true reward stays in each
    step's `info["true_reward"]`. Each session's row goes to SB3's logger under seqrank's
    metric names.

    Args:
        env: a seqrank task name (`walker_walk`, `dmc:...`, `gym:ID`, ...), a
            gymnasium.Env or an SB3 VecEnv. For a name or an Env with a Box action space,
            actions are rescaled to [-1, 1] as seqrank's agents act; an Env with a Discrete
            action space (for DQN, A2C, PPO) and a VecEnv are used as they are.
        teacher: who answers: a `seqrank train --teacher` value (default oracle; `human`:
            a person at the labelling page), a `FeedbackSource`, or a judge function of
            two `seqrank.Segment`s.
        scale: the presets, small or paper; auto (default): paper on CUDA, else small.
        pretrain: PEBBLE's state-entropy pre-training until the first session (after
            `seed_steps + unsup_steps`); None (default): on for SAC and TD3 only. The
            agent's batches get that reward from its replay buffer: make it with
            `replay_buffer_class=PreferenceReplayBuffer`.
        reset_critic: a fresh critic after the first session, then
            `updates_after_reset` updates; None (default): on for SAC and TD3 only.
        n_envs: environments made of a task name (default 1); for your own environment
            pass a VecEnv of as many.
        wait_for_feedback: True (default): `learn` waits for each session's answers;
            False: sessions after the first are answered (by a person, say) in the
            background while the agent trains on, and count once complete.
        page: the labelling page's `labelling.app.ServerOptions` (port, ...); None: its
            defaults.
        label_dir: with `teacher="human"`: the folder of the label database.
        verbose: SB3's callback verbosity.
        **settings: the feedback settings of `seqrank train`, same names and defaults
            (scheme, max_feedback, reward_batch, feedback_frequency, segment_length,
            selection, augment, reward_learner, query_episodes, reward_*, seed_steps,
            unsup_steps, steps, device, ...); a bad value raises `seqrank train`'s
            SettingError before anything is made, an agent setting names where it goes.

    Attributes:
        env: the VecEnv to give the agent, rewarded by the learned reward.
        config: the resolved settings (a `TrainConfig`).
        metrics: each session's metric row so far.
        state: everything the feedback holds (`sb3.state.FeedbackState`), as `save`
            writes it.

    Examples:
        >>> from seqrank.sb3 import PreferenceFeedback
        >>> from stable_baselines3 import SAC
        >>> feedback = PreferenceFeedback("gym:Pendulum-v1", scheme="root", steps=2_000,
        ...     max_feedback=20, reward_batch=10, feedback_frequency=500, seed_steps=200,
        ...     unsup_steps=300)
        >>> from seqrank.sb3 import PreferenceReplayBuffer
        >>> model = SAC("MlpPolicy", feedback.env, seed=0,
        ...     replay_buffer_class=PreferenceReplayBuffer)  # pre-training's reward
        >>> model.learn(2_000, callback=feedback)  # doctest: +SKIP
        >>> feedback.env.num_envs, feedback.config.sessions, len(feedback.labels)
        (1, 2, 0)
    """

    def __init__(
        self,
        env: Any,
        *,
        teacher: str | FeedbackSource | Callable[..., Any] = "oracle",
        scale: str = "auto",
        pretrain: bool | None = None,
        reset_critic: bool | None = None,
        n_envs: int = 1,
        wait_for_feedback: bool = True,
        page: Any = None,
        label_dir: str | Path | None = None,
        verbose: int = 0,
        **settings: Any,
    ):
        super().__init__(verbose)
        name, preset = task_names(env)
        options = sb3_options(
            env, pretrain=pretrain, reset_critic=reset_critic, n_envs=n_envs,
            wait_for_feedback=wait_for_feedback,
        )  # fmt: skip
        spec = teacher if isinstance(teacher, str) else "oracle"
        extra: dict[str, Any] = {"record_states": 1} if spec == "human" else {}
        if options["pretrain"] is False:  # no pre-training: the first session after seed_steps
            extra["unsup_steps"] = 0
        config = _resolve(
            name, preset, scale, {"teacher": spec, **settings, **extra}, options["pretrain"]
        )
        check_page_keywords(env, teacher, label_dir, page)
        task = describe_task(env, options["n_envs"], config.seed)
        if task.episode_length is not None:
            check_episode_fits(config, task.episode_length, task.has_terminals)
        source = make_teacher(teacher, task.obs_dim, config)
        opened = None
        if source is None:  # the person at the labelling page
            from seqrank.sb3.page import open_page

            assert label_dir is not None
            opened, source = open_page(Path(label_dir), config, task.obs_dim, task.act_dim, page)
        device = resolve_device(config.device)
        run = FeedbackRun(
            config, source, task.obs_dim, task.act_dim, task.episode_length or 1, device,
            options["wait_for_feedback"],
        )  # fmt: skip
        venv = task.venv if task.venv is not None else task_vec_env(task.sims or [], config.seed)
        seeded = [e.env for e in getattr(venv, "envs", []) if isinstance(e.env, SeededEpisodes)]
        record = bool(config.record_states)
        vec_env = PreferenceVecEnv(venv, run.episodes, run.learned_reward, task.sims, record)
        self.state = FeedbackState(
            config, options, isinstance(env, str), task, run, vec_env, seeded, opened
        )

    # ---- the contract ---------------------------------------------------------------
    @property
    def env(self) -> PreferenceVecEnv:
        return self.state.env

    @property
    def config(self) -> TrainConfig:
        return self.state.config

    @property
    def metrics(self) -> list[dict[str, Any]]:
        return self.state.metrics

    @property
    def run(self) -> FeedbackRun:
        """seqrank's parts: reward model, sessions, episodes, counters."""
        return self.state.run

    @property
    def page(self) -> Any:
        """The labelling page (teacher="human"), else None."""
        return self.state.page

    @property
    def labels(self) -> LabelStore:
        """Every labelled pair so far, asked and inferred (`len` counts them).

        Examples:
            >>> from seqrank.sb3 import PreferenceFeedback
            >>> len(PreferenceFeedback("gym:Pendulum-v1").labels)  # before any session
            0
        """
        return self.run.labels

    def reward(self, observations: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """The learned reward (ensemble mean) of a batch, as the agent gets it.

        Args:
            observations: (N, obs_dim), or (N, *observation shape).
            actions: (N, act_dim) (or (N,) for a one-number action), or (N,) action
                indices of a discrete space, as `feedback.env` takes them: in its action
                space, which for a task name or a gymnasium.Env with a Box action space is
                [-1, 1] already. SB3's replay buffer keeps a Box action scaled to [-1, 1]:
                for a VecEnv of another range, pass `model.policy.unscale_action(actions)`.

        Returns:
            (N,) rewards; 0 before the first session. A batch of other shapes (before the
                first session too) raises a ValueError naming the expected and received
                shapes.

        Examples:
            >>> import numpy as np
            >>> from seqrank.sb3 import PreferenceFeedback
            >>> feedback = PreferenceFeedback("gym:Pendulum-v1")
            >>> feedback.reward(np.zeros((2, 3)), np.zeros((2, 1)))  # no session yet
            array([0., 0.], dtype=float32)
        """
        space = self.env.action_space
        obs, acts = reward_batch(self.env.observation_space, space, observations, actions)
        return self.run.learned_reward(obs, acts)

    def save(self, path: str | Path) -> None:
        """Save settings, labels, reward model, episodes, counters and random streams.

        With SB3's `model.save` and `model.save_replay_buffer` a run continues from there
        (`PreferenceFeedback.load`) as if uninterrupted when stopped at an episode end; one
        saved within an episode is refused when it would train again.

        Args:
            path: the folder (made if needed): settings.json, labels.jsonl (seqrank's
                label format, for `--teacher replay:FILE`), metrics.jsonl, feedback.pt.

        Examples:
            >>> import os
            >>> from seqrank.sb3 import PreferenceFeedback
            >>> PreferenceFeedback("gym:Pendulum-v1").save("my-run")
            >>> sorted(os.listdir("my-run"))
            ['feedback.pt', 'labels.jsonl', 'metrics.jsonl', 'settings.json']
        """
        saving.save(self.state, getattr(self, "model", None), Path(path))

    @classmethod
    def load(cls, path: str | Path, env: Any = None, **options: Any) -> PreferenceFeedback:
        """The feedback saved in `path` by `save`, ready to train on.

        Args:
            path: the folder `save` wrote.
            env: the environment, as the constructor takes it; None (default): the saved
                task name (your own environment must be passed again).
            **options: constructor keywords that replace the saved ones; `teacher=` must
                be passed again for a source that is not a teacher value.

        Returns:
            The feedback, with its labels, reward model, episodes and counters: load the
                SB3 model with `env=feedback.env` and call its `learn` with
                `reset_num_timesteps=False`.

        Examples:
            >>> from seqrank.sb3 import PreferenceFeedback
            >>> PreferenceFeedback("gym:Pendulum-v1", scheme="ranked").save("my-run")
            >>> feedback = PreferenceFeedback.load("my-run")
            >>> feedback.config.task, feedback.config.scheme
            ('gym:Pendulum-v1', <SchemeName.RANKED: 'ranked'>)
        """
        first, keywords = saving.saved_keywords(Path(path), env, options)
        feedback = cls(first, **keywords)
        saving.restore(feedback.state, Path(path))
        return feedback

    def close(self) -> None:
        """Stop the labelling page, if any (its answers are saved already)."""
        if self.state.page is not None:
            self.state.page.close()
            self.state.page = None

    # ---- SB3's callback hooks ----------------------------------------------------------
    def _init_callback(self) -> None:
        model, kind, state = self.model, type(self.model).__name__, self.state
        if state.resumed is not None:
            saving.check_continuable(state.resumed)
        if not agents.acts_on(model, self.env):
            raise ValueError(
                f"the agent's environment is not feedback.env: make it on feedback.env, "
                f"{kind}('MlpPolicy', feedback.env, ...), which gives it the learned reward "
                "and records the episodes the questions are about"
            )
        off_policy = agents.is_off_policy(model)
        state.pretraining = pebble_default(
            kind, state.options["pretrain"], not off_policy, "pretrain"
        )
        reset = state.options["reset_critic"]
        state.critic_reset = pebble_default(kind, reset, not off_policy, "reset_critic")
        if not state.pretraining and state.config.unsup_steps:
            state.config = without_pretraining(state.config)
        if isinstance(model, OffPolicyAlgorithm):
            assert model.replay_buffer is not None, "the agent's replay buffer is made with it"
            true = state.resumed.true if state.resumed is not None else None
            state.table = ReplayTable(model.replay_buffer, state.run.device, true)
        else:
            state.table = EpisodeTable(
                state.run.episodes, state.run.reward_model.reward, state.run.device
            )
        state.run.use_table(state.table)
        if state.pretraining and state.run.counters.sessions == 0:
            self._entropy_batches(model, kind)

    def _entropy_batches(self, model: Any, kind: str) -> None:
        """Until the first session, the agent's batches carry the state-entropy reward."""
        buffer = model.replay_buffer
        if not isinstance(buffer, PreferenceReplayBuffer):
            raise SettingError(
                f"{setting('pretrain')}: {kind} pre-trains on the state-entropy reward, which "
                f"its replay buffer gives: make it {kind}('MlpPolicy', feedback.env, "
                "replay_buffer_class=PreferenceReplayBuffer) (from seqrank.sb3), or pass "
                "pretrain=False"
            )
        buffer.entropy = EntropyReward(self.config.knn_k, self.run.entropy_stats)

    def _on_training_start(self) -> None:
        resumed = self.state.resumed
        if resumed is not None:  # once: the streams as they were saved
            restore_rng(resumed.global_rng, self.model)
            self.state.resumed = None

    def _on_step(self) -> bool:
        if isinstance(self.state.table, ReplayTable):
            infos = self.locals["infos"]
            self.state.table.store_true(np.array([info["true_reward"] for info in infos]))
        return True

    def _on_rollout_end(self) -> None:
        c = self.run.counters
        c.step = self.num_timesteps
        if c.step < self.config.first_session_step:
            return
        feedback_step(self.run.sessions, c, self._learn_from)
        if self.state.page is not None:
            self.state.page.training(c.step)

    def _learn_from(self, answered: AnsweredSession | None) -> None:
        if answered is None:
            return
        run, state = self.run, self.state
        buffer = getattr(self.model, "replay_buffer", None)
        if isinstance(buffer, PreferenceReplayBuffer):
            buffer.entropy = None  # pre-training ends with the first session
        updates = self.config.updates_after_reset

        def reset() -> None:
            if state.critic_reset:
                agents.reset_critic(self.model, updates)

        row = learn_from_session(
            answered, run.labels, run.counters, run.reward, self.config.seed, reset
        )
        state.metrics.append(row)
        for name, value in scalars(row).items():
            self.logger.record(name, value)
        self.logger.dump(self.num_timesteps)


def _resolve(
    name: str, preset: str, scale: str, settings: dict[str, Any], pretrain: bool | None
) -> TrainConfig:
    """The feedback's run config; a budget that only the default pre-training makes
    impossible says how to drop it (the agent, SAC or not, is not known yet)."""
    try:
        return feedback_config(name, preset, scale, settings)
    except SettingError as problem:
        pretraining_by_default = pretrain is None and "unsup_steps" not in settings
        if pretraining_by_default and "impossible budget" in str(problem):
            raise SettingError(
                f"{problem} (the steps count the pre-training SAC and TD3 do by default; "
                "for an agent that does not pre-train, DQN, PPO, A2C or another, pass "
                "pretrain=False)"
            ) from None
        raise
