"""Starting a run so that it never leaves a directory nobody can use.

- `start_new`: the directory is checked and locked before anything is written; when the
  trainer cannot be built (a replay file that is not there, a segment longer than the
  task's episodes, settings that do not fit in memory) or its building is interrupted (a
  second Ctrl-C, said in a line) everything written is removed again, so the same command
  can run once the problem is fixed.
- `continue_run`: locks the run, reads its saved settings (checked against the expected
  ones when given, naming each difference) and its checkpoint; a finished run (with
  `summary.json`) is returned untouched, with no trainer.
- `open_or_start`: either, for the callers that rerun the same settings (sweeps, the API,
  the user study).

The caller holds the run's lock (`Started.run`) until it is done and then releases it
(a process that ends releases it too).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from seqrank.config import TrainConfig, config_differences, validate
from seqrank.config.rules import with_unread_crowd_defaults
from seqrank.errors import SettingError, setting
from seqrank.training.runs import RunDir

Factory = Callable[[TrainConfig, RunDir], Any]


@dataclass
class Started:
    run: RunDir
    config: TrainConfig
    trainer: Any  # None: the run is finished
    resumed: bool

    @property
    def finished(self) -> bool:
        return self.trainer is None


def build_trainer(factory: Factory, config: TrainConfig, run: RunDir) -> Any:
    """`factory(config, run)`; settings that do not fit in memory are a ValueError."""
    import torch

    try:
        return factory(config, run)
    except (MemoryError, torch.OutOfMemoryError, RuntimeError) as error:
        text = str(error)
        if not isinstance(error, MemoryError) and "allocate" not in text:
            raise
        raise SettingError(
            f"the run's settings need more memory than there is ({_first_line(text)}); lower "
            f"{setting('steps')} ({config.steps}: the replay buffer holds every step), "
            f"{setting('hidden')}, {setting('batch')} or the reward model's sizes"
        ) from None


def _first_line(text: str) -> str:
    asked = re.search(r"tried to allocate (\d+) bytes", text)
    if asked:
        return f"{int(asked.group(1)) / 2**30:,.1f} GiB in one piece"
    line = text.strip().splitlines()[0] if text.strip() else "out of memory"
    return line.split("] ")[-1][:160]


def start_new(
    path: Path,
    config: TrainConfig,
    device: str,
    factory: Factory,
    wandb: str | None = None,
    say: Callable[[str], None] | None = None,
) -> Started:
    """A new run; `say` gets the line that says a second Ctrl-C while the trainer is built
    removed the directory again (there is nothing to resume yet)."""
    run = RunDir.create(path, config, device, wandb)
    try:
        trainer = build_trainer(factory, config, run)
    except KeyboardInterrupt:
        said = run.discard_interrupted("while preparing the run")
        if say is not None:
            say(said)
        raise
    except BaseException:
        run.discard()
        raise
    return Started(run, config, trainer, resumed=False)


def continue_run(path: Path, factory: Factory, expected: TrainConfig | None = None) -> Started:
    run = RunDir.open(path)
    run.lock()
    try:
        config = with_unread_crowd_defaults(run.read_config())
        if expected is not None:
            expected = with_unread_crowd_defaults(expected)
        if expected is not None and config != expected:
            changed = "; ".join(config_differences(config, expected))
            raise ValueError(
                f"{path} holds a run with other settings ({changed}); move it away or "
                "restore the settings it was made with"
            )
        if run.finished:
            return Started(run, config, None, resumed=True)
        validate(config)  # a config.json edited by hand, or written under other rules
        state = run.load_checkpoint()
        trainer = build_trainer(factory, config, run)
        if state is None:  # killed before its first checkpoint: start over
            run.truncate_metrics(0)
        else:
            trainer.load_checkpoint(state)
    except BaseException:
        run.release()
        raise
    return Started(run, config, trainer, resumed=True)


def open_or_start(
    path: Path, config: TrainConfig, device: str, factory: Factory, wandb: str | None = None
) -> Started:
    """Continue the run in `path` when it holds one of these settings, else start it."""
    if (Path(path) / "config.json").exists():
        return continue_run(path, factory, expected=config)
    return start_new(path, config, device, factory, wandb)
