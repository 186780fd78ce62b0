"""Fine-tuning a policy trained elsewhere: the paper's user study (supplementary D.7,
Table 3, the first row of Table 8).

`start_from` puts a saved run's agent, reward model, replay buffer and recent episodes into a
new trainer, which then trains `steps` more steps (Table 3: 400, learning rate 1e-8, 20
answers in two sessions of 10 every 200 steps). The study's two parts choose what the
clips show (its instructions: "In the first run, you will watch low-performing
trajectories. In the second run, you will observe trajectories with varying
performance"): before a session, `refill_for_part` replaces the episodes that segments are
cut from with episodes of the current policy whose actions are replaced by random ones
with the part's probabilities (all random for the lowest skill, none for the highest).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from seqrank.agents.protocol import Agent
from seqrank.buffer import ReplayBuffer
from seqrank.envs import SimEnv
from seqrank.envs.recorder import EpisodeRecorder
from seqrank.episodes import Episode, EpisodeStore
from seqrank.reward.model import RewardModel
from seqrank.training.state import episode_seed

# supplementary Table 3 (cheetah_run from real human feedback); 30-frame clips as the
# study's instructions say; no warm-up or pre-training: the policy is trained already
FINETUNE_PRESET: dict[str, Any] = {
    "actor_lr": 1e-8,
    "critic_lr": 1e-8,
    "feedback_frequency": 200,
    "max_feedback": 20,
    "reward_batch": 10,
    "steps": 400,
    "seed_steps": 0,
    "unsup_steps": 0,
    "segment_length": 30,
    "updates_after_reset": 0,
    "eval_every": 400,
    "checkpoint_every": 200,
}

# per part (`config.rules.FINETUNE_PARTS`): the probability that a step's action is random, one
# episode per value
PARTS: dict[str, tuple[float, ...]] = {
    "low": (1.0, 0.9, 0.8, 0.7),
    "varied": (0.0, 0.25, 0.5, 0.75, 1.0),
}


def start_from(
    state: dict[str, Any],
    agent: Agent,
    reward_model: RewardModel,
    replay: ReplayBuffer,
    episodes: EpisodeStore,
) -> None:
    """The saved run's agent, reward model, replay buffer and episodes (its checkpoint
    `state`) loaded into a new run's; counters, random streams and labels start afresh."""
    agent.load_state_dict(state["agent"])
    reward_model.load_state_dict(state["reward_model"])
    replay.load_state_dict(state["replay"])
    episodes.load_state_dict(state["episodes"])


def play_episodes(
    env: SimEnv, agent: Agent, random_share: tuple[float, ...], seed: int
) -> list[Episode]:
    """One episode per value: the current policy (stochastic), each action replaced by a
    uniform random one with that probability; physics states kept for the clips."""
    rng = np.random.default_rng(seed)
    generator = torch.Generator().manual_seed(seed)
    episodes = []
    for k, share in enumerate(random_share):
        recorder = EpisodeRecorder(record_states=True)
        obs, info = env.reset(seed=episode_seed(seed, 2, k))
        done = False
        while not done:
            action = (
                rng.uniform(-1.0, 1.0, env.act_dim).astype(np.float32)
                if rng.random() < share
                else agent.act(obs, False, generator)
            )
            recorder.before_step(env)
            next_obs, reward, terminated, truncated, _ = env.step(action)
            recorder.add(obs, env.canonical_action(action), float(reward))
            obs, done = next_obs, terminated or truncated
        episodes.append(recorder.finish(info.get("task_index")))
    return episodes


def refill_for_part(
    env: SimEnv,
    agent: Agent,
    episodes: EpisodeStore,
    run_seed: int,
    parts: tuple[str, ...],
    session: int,
) -> None:
    """Before session `session`: the episodes of its part (the last part for later ones)."""
    part = parts[min(session, len(parts) - 1)]
    seed = episode_seed(run_seed, 3, session)
    episodes.episodes.clear()
    for episode in play_episodes(env, agent, PARTS[part], seed):
        episodes.add(episode)
