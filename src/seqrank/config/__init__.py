"""A run's configuration: one frozen `TrainConfig` per run, the CLI options, the saved
config.json and the presets at once.

- `train_config`: `TrainConfig`, each field declared with its role and, for a number, its
  range (`roles.declare`), and `settings_of(role, ...)`.
- `roles`: `Role`, what part of a run a setting configures; the lists that treat settings
  alike are derived from it (`baselines.unread_settings`, what `sb3.PreferenceFeedback`
  refuses, the key of the true-reward reference).
- `ranges`: the values a numeric setting accepts, and their check.
- `resolve`: `resolve_config` (suite defaults, Table 2, the size preset, the user's
  overrides), `validate`, `config_differences`.
- `rules`: the rules settings keep together; what a replayed label file fixes.
- `presets`: the suite defaults, Table 2 and the size presets.
- `baselines`: `unread_settings`, what a baseline run never reads.
"""

from __future__ import annotations

from seqrank.config.baselines import unread_settings
from seqrank.config.resolve import config_differences, resolve_config, validate
from seqrank.config.roles import Role
from seqrank.config.train_config import PRECISIONS, SCALES, TrainConfig, settings_of

__all__ = [
    "PRECISIONS",
    "SCALES",
    "Role",
    "TrainConfig",
    "config_differences",
    "resolve_config",
    "settings_of",
    "unread_settings",
    "validate",
]
