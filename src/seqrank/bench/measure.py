"""Side-by-side timings of the reference and fast paths, in one process.

Each measurement builds its own agent / reward model / trainer from the same settings, so
the two paths only differ in the code they run. The caller interleaves the paths and takes
medians over repeats.
"""

from __future__ import annotations

import contextlib
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from seqrank.agents.sac.precision import matmul_precision
from seqrank.buffer import ReplayBuffer
from seqrank.choices import Device, Precision, TrainingPath
from seqrank.config import TrainConfig
from seqrank.training.agent_factory import make_sac
from seqrank.training.feedback_parts import make_reward_model
from seqrank.training.runs import RunDir
from seqrank.training.runtime import Runtime
from seqrank.training.trainer import Trainer

BUFFER_ROWS = 20_000  # transitions in the benchmark's replay buffer
REWARD_PAIRS = 1_000  # labelled pairs in the reward-training benchmark (400 asked + inferred)


def synchronize(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def _timed(device: torch.device, work: Callable[[], None]) -> float:
    synchronize(device)
    started = time.perf_counter()
    work()
    synchronize(device)
    return time.perf_counter() - started


class _Dims:
    """Observation and action sizes of a task, without keeping its simulator open."""

    def __init__(self, task: str):
        from seqrank.envs import make_env

        env = make_env(task, 0)
        self.obs_dim, self.act_dim, self.discrete = env.obs_dim, env.act_dim, env.discrete
        self.episode_length = env.episode_length
        env.close()


def update_microseconds(
    config: TrainConfig, device: torch.device, fast: bool, precision: str, updates: int
) -> dict[str, float]:
    """Mean time of one SAC update in the trainer's hot loop, and the capture time."""
    dims = _Dims(config.task)
    torch.manual_seed(0)
    agent = make_sac(config, dims, Runtime(device, fast, precision))
    storage = device if fast else torch.device("cpu")
    buffer = ReplayBuffer(BUFFER_ROWS, dims.obs_dim, dims.act_dim, device, storage)
    rng = np.random.default_rng(0)
    rows = rng.standard_normal((BUFFER_ROWS, buffer.width)).astype(np.float32)
    rows[:, -1] = 1.0  # not done
    buffer.table.copy_(torch.from_numpy(rows))
    buffer.index = buffer.size = BUFFER_ROWS
    buffer.size_t.fill_(BUFFER_ROWS)
    generator = torch.Generator().manual_seed(0)

    def one() -> None:
        agent.update_from(buffer, config.batch, generator)

    def many() -> None:
        for _ in range(updates):
            one()

    with matmul_precision(precision):
        agent.update(buffer.sample(config.batch, generator), generator)  # optimiser state
        first = _timed(device, one)  # includes the graph capture on CUDA
        seconds = _timed(device, many)
    capture = float(getattr(agent, "capture_seconds", 0.0))
    return {"us": 1e6 * seconds / updates, "capture_s": capture, "first_s": first}


def reward_epoch_microseconds(
    config: TrainConfig, device: torch.device, fast: bool, precision: str, epochs: int
) -> float:
    """Mean time of one reward-model epoch over REWARD_PAIRS labelled pairs."""
    dims = _Dims(config.task)
    torch.manual_seed(0)
    features = dims.obs_dim + dims.act_dim
    model = make_reward_model(config, features, device)
    generator = torch.Generator().manual_seed(0)
    segments = torch.randn((REWARD_PAIRS, config.segment_length, features), generator=generator)
    first = torch.randint(0, REWARD_PAIRS, (REWARD_PAIRS,), generator=generator)
    second = torch.randint(0, REWARD_PAIRS, (REWARD_PAIRS,), generator=generator)
    labels = torch.randint(0, 2, (REWARD_PAIRS,), generator=generator).float()
    segments, first, second, labels = (t.to(device) for t in (segments, first, second, labels))

    def train(count: int) -> None:  # stop_accuracy above 1: every epoch runs
        minibatch = config.reward_minibatch
        model.train(segments, first, second, labels, count, minibatch, 2.0, generator, not fast)

    with matmul_precision(precision):
        train(1)  # warm-up: allocator, kernels
        seconds = _timed(device, lambda: train(epochs))
    return 1e6 * seconds / epochs


def loop_rates(
    config: TrainConfig, device: torch.device, fast: bool, precision: str, steps: int
) -> dict[str, float]:
    """The full training loop: steps per second after the first feedback session, the
    mean microseconds of its collection step (the action, the simulator's step and the
    transition stored with its learned reward: the loop's cost beside the update), and the
    seconds training waits for that session and for one evaluation episode (the fast path
    evaluates in another process: only the hand-over counts)."""
    dims = _Dims(config.task)
    # the first session right after one random episode: no pre-training, whose updates
    # would only lengthen the bench (the steady state after the session is what is timed)
    first = dims.episode_length
    config = replace(
        config,
        path=TrainingPath.FAST if fast else TrainingPath.REFERENCE,
        precision=Precision(precision),
        seed_steps=dims.episode_length,
        unsup_steps=0,
        steps=first + steps,
        max_feedback=config.reward_batch,
        feedback_frequency=first + steps,
        eval_every=first + steps,
        eval_episodes=1,
        checkpoint_every=10 * (first + steps),
        device=Device(device.type),
    )
    marks: dict[int, float] = {}
    with tempfile.TemporaryDirectory(prefix="seqrank-bench-") as folder:
        trainer = Trainer(config, RunDir.create(Path(folder) / "run", config, device.type))
        durations: dict[str, float] = {"feedback_session": 0.0, "evaluation": 0.0}
        trainer.phase_timer = _phase_timer(durations, device)

        def mark(step: int, live: dict[str, Any]) -> None:
            synchronize(device)
            marks.setdefault(step, time.perf_counter())

        trainer.progress = mark
        collecting = _timed_collection(trainer)
        trainer.train()
    start = first + 100  # after the session and its updates_after_reset updates
    end = first + steps - 100  # before the final evaluation
    if end <= start or start not in marks or end not in marks:
        raise ValueError(f"--loop-steps {steps} is too short: it needs at least 300")
    window = [seconds for step, seconds in collecting.items() if start < step <= end]
    return {
        "steps_per_s": (end - start) / (marks[end] - marks[start]),
        "collect_us": 1e6 * sum(window) / len(window),
        "session_s": durations["feedback_session"],
        "eval_episode_s": durations["evaluation"],
    }


def _timed_collection(trainer: Trainer) -> dict[int, float]:
    """Seconds of each collection step, by the step count it ended at."""
    seconds: dict[int, float] = {}
    collector, step = trainer.collector, trainer.collector.step

    def timed(*args: Any) -> bool:
        started = time.perf_counter()
        episode_over = step(*args)
        seconds[trainer.counters.step] = time.perf_counter() - started
        return episode_over

    collector.step = timed  # type: ignore[method-assign,assignment]
    return seconds


def _phase_timer(
    durations: dict[str, float], device: torch.device
) -> Callable[[str], contextlib.AbstractContextManager[None]]:
    """A trainer's phase timer that records how long each phase's (last) run took."""

    @contextlib.contextmanager
    def timed(name: str) -> Iterator[None]:
        synchronize(device)
        started = time.perf_counter()
        yield
        synchronize(device)
        durations[name] = time.perf_counter() - started

    return timed
