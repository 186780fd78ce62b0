"""Policy evaluation in a separate process, so the fast path's training never waits for it.

The trainer hands over a host copy of the actor's weights and the episode seeds; the worker
(one process, one thread, its own simulator) plays the deterministic policy and returns
the scores. Results are collected at a fixed number of steps after submission (or at the
end), so the metrics file has the same rows in the same order whatever the timing.
Evaluations still pending at a checkpoint are saved in it (weights and seeds) and
submitted again on resume, so a resumed run still reproduces an uninterrupted one.
"""

from __future__ import annotations

import multiprocessing
import signal
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from seqrank.agents.sac.networks import Actor
from seqrank.training.evaluation import PolicyScore, evaluate_policy

_WORKER: dict[str, Any] = {}


class GreedyActor:
    """`evaluate_policy`'s agent: tanh of the policy mean, on the worker's CPU."""

    def __init__(self, actor: Actor):
        self.actor = actor

    @torch.no_grad()
    def act(self, obs: Any, deterministic: bool, generator: torch.Generator) -> Any:
        head = self.actor.net(torch.as_tensor(obs, dtype=torch.float32)[None])
        return torch.tanh(head.chunk(2, dim=-1)[0])[0].numpy()


def _start(task: str, seed: int, dims: tuple[int, int, int, int]) -> None:
    from seqrank.envs import make_env

    torch.set_num_threads(1)
    # Ctrl-C reaches the whole process group: the trainer stops at its next episode end and
    # still needs this process until then
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER["env"] = make_env(task, seed)
    _WORKER["actor"] = Actor(*dims)


def _evaluate(actor_state: dict[str, torch.Tensor], seeds: list[int]) -> PolicyScore:
    actor: Actor = _WORKER["actor"]
    actor.load_state_dict(actor_state)
    return evaluate_policy(GreedyActor(actor), _WORKER["env"], seeds, torch.Generator())


@dataclass
class PendingEvaluation:
    step: int
    collect_at: int  # the step at which the trainer waits for it
    row: dict[str, Any]  # what the metrics row holds besides the scores
    seeds: list[int]
    actor_state: dict[str, torch.Tensor]  # a host copy
    future: Future[PolicyScore] | None = None

    def state_dict(self) -> dict[str, Any]:
        return {name: getattr(self, name) for name in PENDING_FIELDS}


PENDING_FIELDS = ("step", "collect_at", "row", "seeds", "actor_state")


class BackgroundEvaluator:
    def __init__(self, task: str, seed: int, obs_dim: int, act_dim: int, hidden: int, layers: int):
        self.pool = ProcessPoolExecutor(
            1,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_start,
            initargs=(task, seed, (obs_dim, act_dim, hidden, layers)),
        )
        self.pending: list[PendingEvaluation] = []

    def submit(self, pending: PendingEvaluation) -> None:
        pending.future = self.pool.submit(_evaluate, pending.actor_state, pending.seeds)
        self.pending.append(pending)

    def due(self, step: int, everything: bool = False) -> list[tuple[PendingEvaluation, Any]]:
        """The evaluations to log now, oldest first, waiting for them if need be."""
        ready = []
        while self.pending and (everything or self.pending[0].collect_at <= step):
            pending = self.pending.pop(0)
            assert pending.future is not None
            ready.append((pending, pending.future.result()))
        return ready

    def state_dict(self) -> list[dict[str, Any]]:
        return [pending.state_dict() for pending in self.pending]

    def close(self) -> None:
        self.pool.shutdown(wait=False, cancel_futures=True)


def host_copy(actor: Actor) -> dict[str, torch.Tensor]:
    return {k: v.detach().to("cpu", copy=True) for k, v in actor.state_dict().items()}


def score_row(score: PolicyScore) -> dict[str, float]:
    returns = score.returns
    return {
        "eval_return": float(np.mean(returns)),
        "eval_return_std": float(np.std(returns)),
        "eval_success_rate": 100.0 * float(np.mean(score.successes)),
    }
