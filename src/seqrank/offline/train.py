"""IQL on a fixed dataset, evaluated in the environment: the offline run's loop.

Each update draws a batch of dataset rows uniformly (the sampler's generator is the run's
only randomness after the networks' initialisation, and a checkpoint keeps it, so a resumed
run continues the same numbers); every `log_every` updates a `train` row, every
`eval_every` updates (and at the last) an evaluation in the environment and a checkpoint.
Evaluation plays one episode per seed with the policy's mean action, the seeds drawn as an
online run's are (`training.state.episode_seed(seed, 1, evaluation, episode)`), and scores
return and success rate (Meta-World's `info["success"]` at any step); the summary's
success is null where the task has no success signal (DMControl), as `dataset info`'s.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import torch

from seqrank.agents.iql import IQL
from seqrank.buffer import Batch
from seqrank.envs import make_env
from seqrank.envs.scoring import Metric, task_metric
from seqrank.offline.dataset import OfflineDataset
from seqrank.offline.settings import OfflineConfig
from seqrank.training.runs import RunDir

Progress = Callable[[int, dict[str, Any]], None]
OBS_STD_FLOOR = 1e-3  # added to each observation's std (LiRE's `compute_mean_std` eps)
PROGRESS_EVERY = 100  # updates between progress calls (and one after each evaluation)


@dataclass
class OfflineCounters:
    step: int = 0  # updates done
    evaluations: int = 0
    train_seconds: float = 0.0
    eval_curve: list[tuple[int, float]] = field(default_factory=list)
    success_curve: list[tuple[int, float]] = field(default_factory=list)

    def state_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


class DatasetTable:
    """The dataset's rows as tensors on the training device, with the rewards trained on."""

    def __init__(self, dataset: OfflineDataset, rewards: np.ndarray, device: torch.device):
        def tensor(values: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(np.asarray(values, np.float32), device=device)

        self.obs, self.action = tensor(dataset.observations), tensor(dataset.actions)
        self.next_obs = tensor(dataset.next_observations)
        self.reward = tensor(rewards).reshape(-1, 1)
        # a time limit is no terminal: only terminations stop the bootstrap
        self.not_done = tensor(~dataset.terminations).reshape(-1, 1)
        self.rows, self.device = len(dataset), device

    def sample(self, batch_size: int, generator: torch.Generator) -> Batch:
        index = torch.randint(self.rows, (batch_size,), generator=generator).to(self.device)
        return Batch(
            self.obs[index],
            self.action[index],
            self.reward[index],
            self.next_obs[index],
            self.not_done[index],
        )


def observation_scale(dataset: OfflineDataset, normalize: bool) -> tuple[np.ndarray, np.ndarray]:
    if not normalize:
        return np.zeros(dataset.obs_dim), np.ones(dataset.obs_dim)
    observations = dataset.observations.astype(np.float64)
    return observations.mean(0), observations.std(0) + OBS_STD_FLOOR


class OfflineTrainer:
    def __init__(
        self,
        config: OfflineConfig,
        run: RunDir,
        dataset: OfflineDataset,
        rewards: np.ndarray,
        device: torch.device,
        progress: Progress | None = None,
        about: dict[str, Any] | None = None,
    ):
        self.config, self.run, self.dataset, self.device = config, run, dataset, device
        self.progress = progress
        self.about = about or {}  # what the summary and checkpoints carry besides
        self.stop_requested: threading.Event | None = None  # set: stop after a checkpoint
        self.env = make_env(dataset.task, config.seed)
        torch.manual_seed(config.seed)  # the networks' initialisation
        mean, std = observation_scale(dataset, config.normalize_observations)
        self.agent = IQL(dataset.obs_dim, dataset.act_dim, config.iql(), device, mean, std)
        self.table = DatasetTable(dataset, rewards, device)
        self.sampler = torch.Generator().manual_seed(config.seed)
        self.counters = OfflineCounters()

    def train(self) -> dict[str, Any]:
        """Update to `config.steps`, then write and return the summary. On a CPU torch
        keeps a core free (`cpu_path.training_threads`): with every core in its pool, small
        updates on a busy 2-core machine ran 20 times slower than on one thread."""
        from seqrank.training.cpu_path import torch_threads, training_threads

        threads = training_threads(True) if self.device.type == "cpu" else torch.get_num_threads()
        with torch_threads(threads):
            return self._train()

    def _train(self) -> dict[str, Any]:
        from seqrank.training.loop import RunStopped

        c, counters = self.config, self.counters
        started = time.perf_counter() - counters.train_seconds
        while counters.step < c.steps:
            if self.stop_requested is not None and self.stop_requested.is_set():
                counters.train_seconds = time.perf_counter() - started
                self.save_checkpoint()
                raise RunStopped(counters.step)
            self.agent.update(self.table.sample(c.batch, self.sampler))
            counters.step += 1
            counters.train_seconds = time.perf_counter() - started
            if counters.step % c.log_every == 0:
                self.log({"kind": "train", **self.agent.last_metrics})
            evaluated = counters.step % c.eval_every == 0 or counters.step == c.steps
            if evaluated:
                self.evaluate()
                counters.train_seconds = time.perf_counter() - started
                self.save_checkpoint()
            if self.progress is not None and (evaluated or counters.step % PROGRESS_EVERY == 0):
                self.progress(counters.step, self.live())
        summary = self.summary()
        self.run.write_summary(summary)
        self.env.close()
        return summary

    def log(self, row: dict[str, Any]) -> None:
        self.run.append_metrics({"step": self.counters.step, **row})

    def evaluate(self) -> None:
        from seqrank.training.evaluation import evaluate_policy
        from seqrank.training.state import episode_seed

        counters, c = self.counters, self.config
        seeds = [episode_seed(c.seed, 1, counters.evaluations, i) for i in range(c.eval_episodes)]
        score = evaluate_policy(self.agent, self.env, seeds, torch.Generator())
        counters.evaluations += 1
        mean_return = float(np.mean(score.returns))
        success = 100.0 * float(np.mean(score.successes))
        counters.eval_curve.append((counters.step, mean_return))
        counters.success_curve.append((counters.step, success))
        self.log(
            {
                "kind": "eval",
                "eval_return": mean_return,
                "eval_return_std": float(np.std(score.returns)),
                "eval_success_rate": success,
                **self.agent.eval_metrics(),
                "updates_per_second": self.updates_per_second,
                "wall_seconds": counters.train_seconds,
            }
        )

    @property
    def updates_per_second(self) -> float:
        return self.counters.step / max(self.counters.train_seconds, 1e-9)

    def live(self) -> dict[str, Any]:
        curve = self.counters.eval_curve
        return {
            "eval_return": curve[-1][1] if curve else None,
            "eval_success_rate": self.counters.success_curve[-1][1] if curve else None,
            "ups": self.updates_per_second,
        }

    def save_checkpoint(self) -> None:
        self.run.save_checkpoint(
            {
                "agent": self.agent.state_dict(),
                "sampler": self.sampler.get_state(),
                "counters": self.counters.state_dict(),
                "metric_rows": len(self.run.read_metrics()),
                **self.about,
            }
        )

    def load_checkpoint(self, state: dict[str, Any]) -> None:
        self.agent.load_state_dict(state["agent"])
        self.sampler.set_state(state["sampler"])
        saved = state["counters"]
        self.counters = OfflineCounters(
            step=saved["step"],
            evaluations=saved["evaluations"],
            train_seconds=saved["train_seconds"],
            eval_curve=[tuple(p) for p in saved["eval_curve"]],
            success_curve=[tuple(p) for p in saved["success_curve"]],
        )
        self.run.truncate_metrics(self.counters.step, state["metric_rows"])

    def summary(self) -> dict[str, Any]:
        """The finished run's numbers; success is None (null) where the task has no success
        signal (DMControl; a Gymnasium task that never recorded one), as `dataset info`
        and the report decide (`envs.scoring.task_metric`)."""
        c, counters, dataset = self.config, self.counters, self.dataset
        returns = [r for _, r in counters.eval_curve]
        successes = [s for _, s in counters.success_curve]
        scored = task_metric(dataset.task, successes) is Metric.SUCCESS
        learned = c.reward == "learned"
        dataset_returns = dataset.episode_returns()
        return {
            "offline": True,
            "task": dataset.task,
            "dataset": c.dataset,
            "reward": c.reward,
            "scheme": c.scheme if learned else None,
            "teacher": c.teacher if learned else None,
            "max_feedback": c.max_feedback if learned else None,
            "seed": c.seed,
            **self.about,
            "steps": counters.step,
            "final_eval_return": returns[-1] if returns else None,
            "best_eval_return": max(returns) if returns else None,
            "final_eval_success_rate": successes[-1] if successes and scored else None,
            "best_eval_success_rate": max(successes) if successes and scored else None,
            "eval_curve": [list(point) for point in counters.eval_curve],  # as JSON reads it
            "success_curve": [list(p) for p in counters.success_curve] if scored else None,
            "dataset_episodes": dataset.episode_count,
            "dataset_transitions": len(dataset),
            "dataset_return_mean": float(dataset_returns.mean()),
            "dataset_return_max": float(dataset_returns.max()),
            "wall_seconds": counters.train_seconds,
            "updates_per_second": self.updates_per_second,
        }
