"""When and where the policy is evaluated: inline (the reference path: the loop waits), or
in a separate process whose scores are logged `eval_every / 2` steps later (the fast
path: training never waits). Both give the loop the same calls."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import torch

from seqrank.agents.protocol import Agent
from seqrank.agents.sac.networks import Actor
from seqrank.envs.base import SimEnv
from seqrank.training.eval_worker import (
    BackgroundEvaluator,
    GreedyActor,
    PendingEvaluation,
    host_copy,
)
from seqrank.training.evaluation import PolicyScore, evaluate_policy


@dataclass(frozen=True)
class Scored:
    step: int
    score: PolicyScore
    context: dict[str, Any]  # what the metrics row holds besides the scores


@dataclass(frozen=True)
class ActorShape:
    """What a separate process needs to rebuild the actor: the task and network sizes."""

    task: str
    seed: int
    obs_dim: int
    act_dim: int
    hidden: int
    layers: int


class Evaluations(Protocol):
    def submit(self, step: int, collect_at: int, context: dict[str, Any], seeds: list[int]) -> None:
        """Evaluate the current policy on one episode per seed."""

    def due(self, step: int, everything: bool) -> list[Scored]:
        """Scores to log now, oldest first (all of them with `everything`)."""
        ...

    def state_dict(self) -> list[dict[str, Any]]:
        """Evaluations submitted but not yet logged (saved in checkpoints)."""
        ...

    def resume(self, pending: list[dict[str, Any]]) -> None: ...

    def close(self) -> None: ...


class InlineEvaluations:
    def __init__(self, agent: Agent, env: SimEnv, generator: torch.Generator, shape: ActorShape):
        self.agent, self.env, self.generator, self.shape = agent, env, generator, shape
        self._ready: list[Scored] = []

    def submit(self, step: int, collect_at: int, context: dict[str, Any], seeds: list[int]) -> None:
        score = evaluate_policy(self.agent, self.env, seeds, self.generator)
        self._ready.append(Scored(step, score, context))

    def due(self, step: int, everything: bool) -> list[Scored]:
        ready, self._ready = self._ready, []
        return ready

    def state_dict(self) -> list[dict[str, Any]]:
        return []

    def resume(self, pending: list[dict[str, Any]]) -> None:
        """Evaluations a fast-path checkpoint left pending are played here, with the
        actor they were submitted with."""
        s = self.shape
        for state in pending:
            actor = Actor(s.obs_dim, s.act_dim, s.hidden, s.layers)
            actor.load_state_dict(state["actor_state"])
            score = evaluate_policy(GreedyActor(actor), self.env, state["seeds"], torch.Generator())
            self._ready.append(Scored(state["step"], score, state["row"]))

    def close(self) -> None:
        pass


class BackgroundEvaluations:
    def __init__(self, actor: Actor, shape: ActorShape):
        self.actor, self.shape = actor, shape
        self._worker: BackgroundEvaluator | None = None  # started on first use (spawn)

    def _started(self) -> BackgroundEvaluator:
        if self._worker is None:
            s = self.shape
            self._worker = BackgroundEvaluator(
                s.task, s.seed, s.obs_dim, s.act_dim, s.hidden, s.layers
            )
        return self._worker

    def submit(self, step: int, collect_at: int, context: dict[str, Any], seeds: list[int]) -> None:
        pending = PendingEvaluation(step, collect_at, context, seeds, host_copy(self.actor))
        self._started().submit(pending)

    def due(self, step: int, everything: bool) -> list[Scored]:
        if self._worker is None:
            return []
        return [Scored(p.step, score, p.row) for p, score in self._worker.due(step, everything)]

    def state_dict(self) -> list[dict[str, Any]]:
        return [] if self._worker is None else self._worker.state_dict()

    def resume(self, pending: list[dict[str, Any]]) -> None:
        for state in pending:
            self._started().submit(PendingEvaluation(**state))

    def close(self) -> None:
        if self._worker is not None:
            self._worker.close()
            self._worker = None
