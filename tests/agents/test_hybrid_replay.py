"""QPA's hybrid experience replay: the recent share of each batch, on the host and on the
buffer's device, in both training paths, and off by default."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from seqrank.agents.dqn import DQN, DQNSettings, EpsilonSchedule
from seqrank.agents.hybrid_replay import HybridReplay
from seqrank.agents.sac import SAC, Execution, SACSettings
from seqrank.buffer import Batch, BatchSource, ReplayBuffer
from seqrank.config import TrainConfig
from seqrank.feedback.labels import LabelStore
from seqrank.reward.model import RewardModel
from seqrank.training.backbones import BACKBONES, UpdateParts

OBS, ACT = 3, 2


def numbered_buffer(capacity: int, added: int) -> ReplayBuffer:
    """A buffer whose k-th added transition has observation (k, k, k)."""
    buffer = ReplayBuffer(capacity, OBS, ACT, torch.device("cpu"))
    for k in range(added):
        obs = np.full(OBS, k, np.float32)
        buffer.add(obs, np.zeros(ACT, np.float32), 0.0, 0.0, obs, False)
    return buffer


def numbers(batch: Batch) -> np.ndarray:
    return batch.obs[:, 0].numpy().astype(int)


def draw(hybrid: HybridReplay, batch: int, on_device: bool) -> Batch:
    if on_device:
        torch.manual_seed(0)
        return hybrid.sample_on_device(batch)
    return hybrid.sample(batch, torch.Generator().manual_seed(0))


@pytest.mark.parametrize("on_device", [False, True], ids=["host", "device"])
@pytest.mark.parametrize(("capacity", "added"), [(500, 300), (50, 130)], ids=["ring", "wrapped"])
@pytest.mark.parametrize("share", [0.25, 0.5, 1.0])
def test_the_recent_share_of_a_batch_comes_from_the_last_window(on_device, capacity, added, share):
    hybrid = HybridReplay(numbered_buffer(capacity, added), share, window=20)
    seen = numbers(draw(hybrid, 64, on_device))
    recent = round(share * 64)
    assert len(seen) == 64 and hybrid.recent_rows(64) == recent
    # the recent rows (last in the batch) are all from the last 20 added
    assert set(seen[64 - recent :]) <= set(range(added - 20, added))
    # the others are uniform over what the buffer holds: older rows among them
    stored = range(max(0, added - capacity), added)
    assert set(seen[: 64 - recent]) <= set(stored)
    if recent < 64:
        assert min(seen[: 64 - recent]) < added - 20


@pytest.mark.parametrize("on_device", [False, True], ids=["host", "device"])
def test_a_window_larger_than_the_buffer_holds_what_there_is(on_device):
    hybrid = HybridReplay(numbered_buffer(100, 30), 1.0, window=1000)
    assert hybrid.window_rows() == 30
    seen = numbers(draw(hybrid, 256, on_device))
    assert set(seen) <= set(range(30)) and len(set(seen)) > 20


def test_share_zero_draws_what_the_buffer_draws():
    buffer = numbered_buffer(200, 150)
    plain = buffer.sample(32, torch.Generator().manual_seed(5))
    hybrid = HybridReplay(buffer, 0.0, window=10).sample(32, torch.Generator().manual_seed(5))
    assert torch.equal(plain.obs, hybrid.obs)


def test_the_window_survives_a_checkpoint():
    buffer = numbered_buffer(50, 130)
    restored = ReplayBuffer(50, OBS, ACT, torch.device("cpu"))
    restored.load_state_dict(buffer.state_dict())
    assert int(restored.index_t) == buffer.index == 30
    a, b = HybridReplay(buffer, 0.5, 20), HybridReplay(restored, 0.5, 20)
    assert torch.equal(a.indices(64, torch.Generator().manual_seed(1)), b.indices(64, _gen(1)))
    torch.manual_seed(2)
    on_device = a.device_indices(64)
    torch.manual_seed(2)
    assert torch.equal(on_device, b.device_indices(64))


def _gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


class Recording(HybridReplay):
    """A hybrid replay that keeps the batches it gave."""

    def __init__(self, *args: object) -> None:
        super().__init__(*args)  # type: ignore[arg-type]
        self.given: list[Batch] = []

    def sample(self, batch_size: int, generator: torch.Generator) -> Batch:
        batch = super().sample(batch_size, generator)
        self.given.append(batch)
        return batch


@pytest.mark.parametrize("path", ["reference", "fast"])
def test_sac_updates_from_hybrid_batches_in_both_paths(path):
    """On a CPU the fast path samples on the host too (graphs are CUDA only)."""
    settings = SACSettings(
        hidden=16,
        layers=2,
        actor_lr=1e-3,
        critic_lr=1e-3,
        alpha_lr=1e-3,
        init_temperature=0.1,
        discount=0.99,
        tau=0.005,
        target_update_every=2,
    )
    cpu = torch.device("cpu")
    execution = Execution() if path == "reference" else Execution.fast(cpu, "fp32")
    agent = SAC(OBS, ACT, settings, cpu, execution)
    source = Recording(numbered_buffer(400, 300), 0.5, 25)
    before = [p.clone() for p in agent.critic.parameters()]
    for _ in range(3):
        agent.update_from(source, 40, _gen(0))
    assert len(source.given) == 3 and agent.updates == 3
    for batch in source.given:
        assert set(numbers(batch)[20:]) <= set(range(275, 300))
    after = agent.critic.parameters()
    assert any(not torch.equal(a, b) for a, b in zip(before, after, strict=True))


class SourceSpy:
    """An agent that remembers where each update drew its batch."""

    def __init__(self) -> None:
        self.sources: list[BatchSource] = []

    def update_from(self, replay: BatchSource, batch_size: int, gen: torch.Generator) -> None:
        self.sources.append(replay)


def parts_for(agent: object, replay: ReplayBuffer, extra: dict[str, float]) -> UpdateParts:
    model = RewardModel(1, OBS + ACT, 8, 1, 1e-3, torch.device("cpu"))
    return UpdateParts(
        agent,  # type: ignore[arg-type]
        replay,
        model,
        LabelStore(),
        lambda: None,
        extra.__setitem__,
        OBS,
        _gen(0),
        episode_length=10,
    )


def test_hybrid_replay_is_off_by_default_and_the_buffer_itself_is_sampled():
    assert TrainConfig().hybrid_replay == 0
    spy, replay, extra = SourceSpy(), numbered_buffer(100, 50), {}
    update = BACKBONES["pebble"](TrainConfig(batch=8), parts_for(spy, replay, extra))
    update(1, True)
    update(2, False)
    assert spy.sources == [replay, replay] and extra == {}


def test_hybrid_batches_while_feedback_is_open_then_uniform_ones():
    spy, replay, extra = SourceSpy(), numbered_buffer(100, 50), {}
    config = TrainConfig(batch=8, hybrid_replay=0.5, hybrid_episodes=3)
    update = BACKBONES["pebble"](config, parts_for(spy, replay, extra))
    update(1, True)
    hybrid = spy.sources[0]
    assert isinstance(hybrid, HybridReplay) and hybrid.window == 30  # 3 episodes of 10
    assert extra == {"hybrid_recent_share": 0.5, "hybrid_window": 30.0}
    update(2, False)  # the budget is spent: QPA goes back to uniform batches
    assert spy.sources[1] is replay and extra["hybrid_recent_share"] == 0.0


def test_dqn_updates_from_hybrid_batches_too():
    """block:place learns with DQN; it samples through the same `BatchSource`."""
    settings = DQNSettings(
        hidden=16,
        layers=2,
        lr=1e-3,
        discount=0.99,
        tau=0.005,
        target_update_every=2,
        epsilon=EpsilonSchedule(),
    )
    agent = DQN(OBS, ACT, settings, torch.device("cpu"))
    source = Recording(numbered_buffer(400, 300), 0.25, 10)
    agent.update_from(source, 40, _gen(0))
    assert agent.updates == 1 and set(numbers(source.given[0])[30:]) <= set(range(290, 300))
