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

from seqrank.config.roles import Role
from seqrank.config.train_config import ROLES

REFERENCE_FILE = Path(__file__).with_name("true_reward_reference.json")

# The key of the file's entries: the settings that shape how the true-reward agent learns.
# A reference applies to a run only when all of them are equal (evaluation episodes, seeds
# and feedback settings do not matter): seqrank's agent settings but those alike in every
# true-reward run or that compute the same update otherwise, the random warm-up before it
# learns, and the size preset. A new agent setting joins the key, so entries measured
# without it no longer apply (`scripts/make_reference.py` measures them again).
# the backbone: pebble in every baseline; path and precision: how the same update computes
SAME_LEARNING = ("backbone", "path", "precision")
BEYOND_THE_AGENT = ("scale", "seed_steps")
REFERENCE_KEY = tuple(
    name
    for name, role in ROLES.items()
    if name in BEYOND_THE_AGENT or (role is Role.AGENT and name not in SAME_LEARNING)
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


def reference_key(config: dict[str, Any]) -> dict[str, Any]:
    """The settings of a run's config (`config.json`'s content) that pick its reference."""
    return {name: config.get(name) for name in REFERENCE_KEY}


def reference_for(config: dict[str, Any], step: int, path: Path | None = None) -> Reference | None:
    """The measured true-reward return for this run's task and agent at `step`, if any."""
    path = REFERENCE_FILE if path is None else path
    if not path.exists():
        return None
    from seqrank.envs import canonical_task

    task = canonical_task(config["task"])
    settings = reference_key(config)
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
