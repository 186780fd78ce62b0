"""The fast path's first captured update is checked against the eager update on the same
batch; a capture that fails or disagrees leaves the run eager, with one warning line. CUDA
graphs cannot be captured on a CPU, so the CPU tests below fail the capture for real, or
stand in for it with a call that replays eagerly (and one that corrupts the weights)."""

from __future__ import annotations

import copy

import numpy as np
import torch

from seqrank.agents.sac import SAC, Execution, SACSettings
from seqrank.agents.sac import agent as sac_module
from seqrank.buffer import ReplayBuffer

CPU = torch.device("cpu")
SETTINGS = SACSettings(
    hidden=64,
    layers=2,
    actor_lr=5e-4,
    critic_lr=5e-4,
    alpha_lr=1e-4,
    init_temperature=0.1,
    discount=0.99,
    tau=0.005,
    target_update_every=2,
)
OBS, ACT, ROWS = 7, 3, 48
GRAPHS = Execution(stacked_critics=True, fused_adam=True, graphs=True)


class EagerReplay:
    """Stands in for `GraphedCall` on a CPU: "replays" by running the update eagerly."""

    def __init__(self, fn, touched, warmup: bool = True):
        self.fn, self.touched, self.capture_seconds = fn, touched, 0.0

    def __call__(self) -> None:
        self.fn()


class CorruptReplay(EagerReplay):
    """A replay that trains on garbage: every weight moves at random after the update."""

    def __call__(self) -> None:
        self.fn()
        with torch.no_grad():
            for tensor in self.touched():
                if tensor.requires_grad:
                    tensor.add_(torch.randn_like(tensor))


class NanReplay(EagerReplay):
    """A replay whose losses come back not a number."""

    def __call__(self) -> None:
        self.fn()
        with torch.no_grad():
            for tensor in self.touched():
                if not tensor.requires_grad and tensor.dim() == 0:
                    tensor.fill_(float("nan"))


def agent_and_buffer() -> tuple[SAC, ReplayBuffer, torch.Generator]:
    torch.manual_seed(0)
    agent = SAC(OBS, ACT, SETTINGS, CPU, GRAPHS)
    buffer = ReplayBuffer(1000, OBS, ACT, CPU)
    generator = torch.Generator().manual_seed(0)
    for _ in range(300):
        obs = torch.randn(OBS, generator=generator).numpy()
        buffer.add(obs, np.zeros(ACT, np.float32), 0.0, float(obs[0]), obs, False)
    agent.update_from(buffer, ROWS, generator)  # eager: creates the optimisers' state
    return agent, buffer, generator


def warnings_in(captured: str) -> list[str]:
    return [line for line in captured.splitlines() if line.startswith("warning: fast path")]


def test_a_capture_that_raises_leaves_the_run_eager_with_one_warning(capsys):
    agent, buffer, generator = agent_and_buffer()  # a CPU build cannot capture CUDA graphs
    before = [p.detach().clone() for p in agent.actor.parameters()]
    for _ in range(5):
        agent.update_from(buffer, ROWS, generator)
    (line,) = warnings_in(capsys.readouterr().err)
    assert "the captured update failed" in line and "--path reference" in line
    assert agent.fallback is not None and not agent.execution.graphs
    assert agent.updates == 6  # every call made exactly one update
    assert all(not torch.equal(a, b) for a, b in zip(before, agent.actor.parameters(), strict=True))


def test_a_replay_that_agrees_with_the_eager_update_keeps_the_graphs(monkeypatch, capsys):
    monkeypatch.setattr(sac_module, "GraphedCall", EagerReplay)
    agent, buffer, generator = agent_and_buffer()
    for _ in range(5):
        agent.update_from(buffer, ROWS, generator)
    assert warnings_in(capsys.readouterr().err) == []
    assert agent.fallback is None and agent.execution.graphs and agent.graph_checked
    assert agent.updates == 6


def test_a_replay_that_disagrees_is_given_up_for_the_eager_update(monkeypatch, capsys):
    monkeypatch.setattr(sac_module, "GraphedCall", CorruptReplay)
    agent, buffer, generator = agent_and_buffer()
    twin = copy.deepcopy(agent)
    agent.update_from(buffer, ROWS, generator)  # the checked replay
    (line,) = warnings_in(capsys.readouterr().err)
    assert "points elsewhere than the eager one's" in line
    assert not agent.execution.graphs and agent.updates == 2
    # the agent holds the eager update of the replay's batch and noise, not the garbage
    assert agent._graph_inputs is not None
    twin.update_with_noise(*agent._graph_inputs)
    for mine, theirs in zip(agent.actor.parameters(), twin.actor.parameters(), strict=True):
        torch.testing.assert_close(mine, theirs, rtol=0, atol=1e-6)
    for _ in range(3):
        agent.update_from(buffer, ROWS, generator)
    assert agent.updates == 5 and warnings_in(capsys.readouterr().err) == []


def test_a_replay_with_a_non_finite_loss_is_given_up(monkeypatch, capsys):
    monkeypatch.setattr(sac_module, "GraphedCall", NanReplay)
    agent, buffer, generator = agent_and_buffer()
    agent.update_from(buffer, ROWS, generator)
    (line,) = warnings_in(capsys.readouterr().err)
    assert "was nan where the eager update gives" in line and not agent.execution.graphs
    assert all(torch.isfinite(p).all() for p in agent.actor.parameters())
