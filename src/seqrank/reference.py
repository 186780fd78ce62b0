"""What a run's return means: measured true-reward returns that ship with the package.

`true_reward_reference.json` holds, per task and agent settings, the evaluation return of
the true-reward agent (`seqrank train --reward true`, the same SAC on the environment's
reward) at each evaluation step: mean and 95% t-interval over seeds, with the command and
results folder that measured it. A run's closing summary sets its own return beside the
entry for the same task, agent settings and step, when there is one.

`scripts/make_reference.py` writes the file from a folder of true-reward runs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REFERENCE_FILE = Path(__file__).with_name("true_reward_reference.json")

# the settings that shape the agent's learning: a reference applies to a run only when all
# of them are equal (evaluation episodes, seeds and feedback settings do not matter)
AGENT_SETTINGS = (
    "scale",
    "hidden",
    "layers",
    "batch",
    "actor_lr",
    "critic_lr",
    "alpha_lr",
    "init_temperature",
    "discount",
    "tau",
    "target_update_every",
    "seed_steps",
)


@dataclass(frozen=True)
class Reference:
    task: str
    step: int
    mean: float
    low: float
    high: float
    seeds: int
    measured: str  # where and how: the results folder and the command

    def describe(self) -> str:
        return f"{self.mean:.1f} [{self.low:.1f}, {self.high:.1f}] ({self.seeds} seeds)"


def agent_settings(config: dict[str, Any]) -> dict[str, Any]:
    return {name: config.get(name) for name in AGENT_SETTINGS}


def reference_for(config: dict[str, Any], step: int, path: Path | None = None) -> Reference | None:
    """The measured true-reward return for this run's task and agent at `step`, if any."""
    path = REFERENCE_FILE if path is None else path
    if not path.exists():
        return None
    from seqrank.envs import canonical_task

    task = canonical_task(config["task"])
    settings = agent_settings(config)
    for entry in json.loads(path.read_text())["entries"]:
        if canonical_task(entry["task"]) != task or entry["settings"] != settings:
            continue
        for point in entry["curve"]:
            if point["step"] == step:
                return Reference(
                    entry["task"],
                    step,
                    point["mean"],
                    point["low"],
                    point["high"],
                    point["seeds"],
                    entry["measured"],
                )
    return None
