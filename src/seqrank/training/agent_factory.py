"""Which agent a run trains, built from its config: SAC for continuous control, DQN (D.1)
for discrete tasks such as block:place. A new agent is registered here."""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import torch

from seqrank.agents.dqn import DQN, DQNSettings, EpsilonSchedule
from seqrank.agents.protocol import Agent
from seqrank.agents.sac import SAC, Execution, SACSettings
from seqrank.config import TrainConfig
from seqrank.envs.base import SimEnv
from seqrank.training.runtime import Runtime


class EnvShape(Protocol):
    @property
    def obs_dim(self) -> int: ...

    @property
    def act_dim(self) -> int: ...

    @property
    def discrete(self) -> bool: ...


def make_agent(config: TrainConfig, env: EnvShape, runtime: Runtime) -> Agent:
    if env.discrete:
        return make_dqn(config, env, runtime.device)
    return make_sac(config, env, runtime)


def make_sac(config: TrainConfig, env: EnvShape, runtime: Runtime) -> SAC:
    settings = SACSettings.from_config(config)
    execution = Execution.fast(runtime.device, runtime.precision) if runtime.fast else Execution()
    return SAC(env.obs_dim, env.act_dim, settings, runtime.device, execution)


def make_dqn(config: TrainConfig, env: EnvShape, device: torch.device) -> DQN:
    settings = DQNSettings(
        hidden=config.hidden,
        layers=config.layers,
        lr=config.critic_lr,
        discount=config.discount,
        tau=config.tau,
        target_update_every=config.target_update_every,
        epsilon=EpsilonSchedule(random_steps=config.seed_steps),
    )
    return DQN(env.obs_dim, env.act_dim, settings, device)


def load_policy(run_dir: Path, env: SimEnv) -> Agent:
    """The agent of a run's last checkpoint on the CPU, to act (the offline labelling
    rollout); ValueError when the run has no checkpoint yet."""
    from seqrank.training.runs import RunDir
    from seqrank.training.runtime import Runtime

    run = RunDir.open(run_dir)
    state = run.load_checkpoint()
    if state is None:
        raise ValueError(f"{run_dir} has no checkpoint yet, so it has no policy to roll out")
    agent = make_agent(run.read_config(), env, Runtime(torch.device("cpu"), False, "fp32"))
    agent.load_state_dict(state["agent"])
    return agent
