"""Settings that make a sweep's runs tiny (a few seconds each on a CPU)."""

from __future__ import annotations

TINY = {
    "steps": 1800,
    "seed_steps": 300,
    "unsup_steps": 900,
    "feedback_frequency": 500,
    "max_feedback": 20,
    "reward_batch": 10,
    "hidden": 32,
    "batch": 32,
    "reward_hidden": 32,
    "reward_epochs": 5,
    "eval_every": 900,
    "eval_episodes": 1,
    "checkpoint_every": 1000,
    "heldout_pairs": 50,
}
