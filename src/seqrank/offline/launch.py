"""Starting an offline run so that bad input leaves nothing behind, and continuing one.

A new run checks everything it can before it writes: its settings, the output folder, the
dataset (there, of the task asked for, of the task's observation and action sizes, with
continuous actions) and the learned reward's budget against the dataset's segments. Only
then is the run directory made; a failure after that (the labelling, the reward fit)
removes it again. A run continued with `--resume` reads its saved settings, reloads its
dataset and refuses one that changed since the run began (`dataset_digest`).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.errors import SettingError, setting
from seqrank.offline.dataset import OfflineDataset
from seqrank.offline.settings import OfflineConfig, validate
from seqrank.offline.train import OfflineTrainer, Progress
from seqrank.training.runs import RunDir

Say = Callable[[str], None]  # a line for the user (the CLI's stderr)


@dataclass
class OfflineStarted:
    run: RunDir
    config: OfflineConfig
    trainer: OfflineTrainer | None  # None: the run is finished
    resumed: bool

    @property
    def finished(self) -> bool:
        return self.trainer is None


def load_checked(config: OfflineConfig) -> OfflineDataset:
    """The run's dataset, or a ValueError naming what does not fit."""
    from seqrank.envs import make_env
    from seqrank.offline.minari_io import load_dataset
    from seqrank.offline.rewards import check_learned_budget

    dataset = load_dataset(config.dataset, config.task)
    env = make_env(dataset.task, config.seed)
    try:
        expected, found = (env.obs_dim, env.act_dim), (dataset.obs_dim, dataset.act_dim)
        discrete = env.discrete
    finally:
        env.close()
    if discrete:
        raise ValueError(
            f"task {dataset.task} has discrete actions; IQL's Gaussian policy needs a task "
            "with continuous ones"
        )
    if expected != found:
        raise ValueError(
            f"dataset {config.dataset} has observations of size {found[0]} and actions of "
            f"size {found[1]}; its task {dataset.task} has {expected[0]} and {expected[1]}: "
            "give a dataset made on this task"
        )
    if config.batch > len(dataset):
        raise SettingError(
            f"{setting('batch')} {config.batch} is more than the {len(dataset)} transitions of "
            f"dataset {config.dataset}; accepted: 1 to {len(dataset)}"
        )
    check_learned_budget(config, dataset)
    return dataset


def dataset_digest(dataset: OfflineDataset) -> str:
    """A fingerprint of the rows a run trains on: a resumed run checks it is the same."""
    digest = hashlib.sha256()
    for column in (dataset.observations, dataset.actions, dataset.rewards,
                   dataset.next_observations, dataset.terminations, dataset.starts):  # fmt: skip
        digest.update(np.ascontiguousarray(column).tobytes())
    return digest.hexdigest()[:16]


def build_trainer(
    config: OfflineConfig,
    run: RunDir,
    dataset: OfflineDataset,
    progress: Progress | None,
    say: Say | None = None,
) -> OfflineTrainer:
    """The trainer on the run's (scaled) rewards; a learned reward is fit here the first
    time (`say` is told, it takes a while) and read back from the run directory after."""
    from seqrank.offline.rewards import (
        LEARNED_REWARDS,
        resolve_scale,
        scale_rewards,
        training_rewards,
    )
    from seqrank.training.runtime import resolve_device

    device = resolve_device(config.device)
    if config.reward == "learned" and not (run.path / LEARNED_REWARDS).is_file() and say:
        say(
            f"labelling the dataset ({config.max_feedback} {config.scheme} questions, "
            f"{config.teacher}) and fitting the reward"
        )
    rewards, feedback = training_rewards(config, dataset, run.path)
    scale = resolve_scale(config.reward_scale, dataset.task)
    scaled = scale_rewards(rewards, dataset.starts, scale)
    about = {"reward_scale": scale.value, "dataset_digest": dataset_digest(dataset)}
    trainer = OfflineTrainer(config, run, dataset, scaled, device, progress, about)
    if feedback is not None:
        trainer.log(feedback)
    return trainer


def start_new(
    path: Path, config: OfflineConfig, progress: Progress | None = None, say: Say | None = None
) -> OfflineStarted:
    validate(config)
    RunDir.check_new(Path(path))
    dataset = load_checked(config)
    from seqrank.training.runtime import resolve_device

    run = RunDir.create(Path(path), config, str(resolve_device(config.device)))
    try:
        trainer = build_trainer(config, run, dataset, progress, say)
    except KeyboardInterrupt:  # a second Ctrl-C: there is nothing to resume yet
        said = run.discard_interrupted(*_interrupted(config, run.path))
        if say is not None:
            say(said)
        raise
    except BaseException:
        run.discard()
        raise
    return OfflineStarted(run, config, trainer, resumed=False)


def _interrupted(config: OfflineConfig, folder: Path) -> tuple[str, str]:
    """What a new run stopped by a second Ctrl-C before its first update was doing, and
    what went with it: the learned reward's labels are not kept then, since every teacher
    a run may ask answers them again when the same command runs (`--teacher human`, the
    page, is refused: its labels come in a label file, outside the run)."""
    from seqrank.offline.rewards import LABELS

    if config.reward != "learned":
        return "while preparing the run", ""
    if not (folder / LABELS).is_file():
        return "while labelling the dataset", ""
    teacher = config.teacher
    return "while fitting the reward", f" and its labels ({teacher}'s; the same command asks again)"


def read_config(run: RunDir) -> OfflineConfig:
    try:
        values: Any = json.loads(run.config_path.read_text())
    except json.JSONDecodeError:
        raise ValueError(f"{run.config_path} is not a run's config (not JSON)") from None
    if not isinstance(values, dict) or "dataset" not in values:
        raise ValueError(f"{run.path} holds no offline run (its config.json names no dataset)")
    return validate(OfflineConfig.from_dict(values))


def continue_run(
    path: Path,
    progress: Progress | None = None,
    expected: OfflineConfig | None = None,
    say: Say | None = None,
) -> OfflineStarted:
    """The stopped run in `path`, ready to train on; a finished one with no trainer."""
    run = RunDir.open(Path(path))
    run.lock()
    try:
        config = read_config(run)
        if expected is not None and config != expected:
            changed = [
                f"{k}: {v!r} there, {expected.as_dict()[k]!r} now"
                for k, v in config.as_dict().items()
                if v != expected.as_dict()[k]
            ]
            raise ValueError(
                f"{path} holds an offline run with other settings ({'; '.join(changed)}); "
                "move it away or restore the settings it was made with"
            )
        if run.finished:
            return OfflineStarted(run, config, None, resumed=True)
        state = run.load_checkpoint()
        dataset = load_checked(config)
        trainer = build_trainer(config, run, dataset, progress, say)
        if state is None:  # stopped before its first checkpoint: start over (the
            run.truncate_metrics(0)  # learned reward's step-0 feedback row stays)
        else:
            if state.get("dataset_digest") != trainer.about["dataset_digest"]:
                raise ValueError(
                    f"dataset {config.dataset} changed since {path} began (its rows differ); "
                    "restore the dataset it was made with, or start a new run"
                )
            trainer.load_checkpoint(state)
    except BaseException:
        run.release()
        raise
    return OfflineStarted(run, config, trainer, resumed=True)


def open_or_start(
    path: Path, config: OfflineConfig, progress: Progress | None = None
) -> OfflineStarted:
    """Continue the run in `path` when it holds one of these settings, else start it."""
    if (Path(path) / "config.json").exists():
        return continue_run(path, progress, expected=config)
    return start_new(path, config, progress)
