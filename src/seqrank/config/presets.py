"""Presets: the suite defaults (SPEC section 2), the paper's Table 2 rows and the size
presets that `resolve_config` applies, in that order, before the user's overrides."""

from __future__ import annotations

from typing import Any

from seqrank.envs import canonical_task

# Supplementary Table 2: lr, feedback frequency, max feedback, reward batch, meta freq, steps.
TABLE2: dict[str, tuple[float, int, int, int, int, int]] = {
    "walker_walk": (5e-4, 20_000, 400, 40, 1_000, 500_000),
    "cheetah_run": (5e-4, 20_000, 200, 20, 1_000, 1_000_000),
    "quadruped_walk": (1e-4, 30_000, 1_000, 100, 1_000, 1_000_000),
    "humanoid_walk": (1e-4, 30_000, 40_000, 500, 10_000, 1_000_000),
    "hopper_hop": (1e-4, 20_000, 4_000, 100, 1_000, 1_000_000),
    "button-press-v3": (3e-4, 5_000, 10_000, 50, 5_000, 1_000_000),
    "door-open-v3": (3e-4, 5_000, 10_000, 200, 10_000, 1_000_000),
    "drawer-open-v3": (3e-4, 5_000, 20_000, 200, 5_000, 1_000_000),
    "sweep-into-v3": (3e-4, 5_000, 10_000, 100, 5_000, 1_000_000),
    "window-open-v3": (3e-4, 5_000, 1_000, 100, 5_000, 1_000_000),
    "hammer-v3": (3e-4, 5_000, 10_000, 30, 10_000, 1_000_000),
}

GYM_DEFAULTS = {"hidden": 256, "layers": 2, "batch": 256, "actor_lr": 3e-4, "critic_lr": 3e-4}

SUITE_DEFAULTS: dict[str, dict[str, Any]] = {
    "dmc": {"hidden": 1024, "layers": 2, "batch": 1024, "reward_epochs": 50},
    # RIME's Meta-World values (`train_RIME.py`, `run_parallel.sh`): beta decays over 600
    # epochs, a fit stops no sooner than its 7th
    "metaworld": {
        "hidden": 256,
        "layers": 3,
        "batch": 512,
        "reward_epochs": 10,
        "rime_decay_updates": 600,
        "rime_min_epochs": 7,
    },
    # Gymnasium tasks (gym:ID, a user's factory): SAC's own MuJoCo settings (Haarnoja et
    # al. 2018: 256 x 2, batch 256, learning rate 3e-4), which SB3 and CleanRL keep; the
    # feedback schedule is the SPEC's defaults (400 answers, 40 every 20 000 steps).
    "gym": GYM_DEFAULTS,
    "custom": GYM_DEFAULTS,
    # block:place, supplementary Table 4 (D.1): DQN; lr 1e-6 for policy and reward, feedback
    # every 200 steps in batches of 50, 3 000 training steps after the 1 000 random steps,
    # 30-step segments. 800 questions do not fit 3 000 steps (15 sessions do: 750).
    "block": {
        "hidden": 256,
        "layers": 2,
        "batch": 64,
        "actor_lr": 1e-6,
        "critic_lr": 1e-6,
        "reward_lr": 1e-6,
        "feedback_frequency": 200,
        "max_feedback": 750,
        "reward_batch": 50,
        "steps": 4_000,
        "seed_steps": 1_000,
        "unsup_steps": 0,
        "segment_length": 30,
        "reward_epochs": 50,
        "updates_after_reset": 0,
        "target_update_every": 1,
        "eval_every": 500,
        "eval_episodes": 20,
        "checkpoint_every": 500,
        "heldout_pairs": 200,
    },
}

# Sized for a 2-core CPU: about 20 minutes for the default walker_walk run.
SMALL_PRESET: dict[str, Any] = {
    "hidden": 256,
    "layers": 2,
    "batch": 256,
    "steps": 60_000,
    "unsup_steps": 4_000,
    "max_feedback": 100,
    "reward_batch": 20,
    "feedback_frequency": 10_000,
    "reward_epochs": 30,
    "eval_every": 10_000,
    "eval_episodes": 5,
    "meta_update_frequency": 1_000,
}


# block:place on a CPU: Table 4's learning rates learn next to nothing from scratch in a few
# thousand steps (the paper fine-tuned a simulator-trained policy), so this preset uses
# usual ones and fewer, smaller sessions.
BLOCK_SMALL_PRESET: dict[str, Any] = {
    "hidden": 128,
    "actor_lr": 1e-3,
    "critic_lr": 1e-3,
    "reward_lr": 1e-3,
    "steps": 6_000,
    "feedback_frequency": 500,
    "max_feedback": 200,
    "reward_batch": 20,
    "reward_epochs": 50,
    "eval_every": 1_000,
    "checkpoint_every": 1_000,
}


def table2_overrides(task: str) -> dict[str, Any]:
    suite, name = canonical_task(task)
    values: dict[str, Any] = {"task": task, **SUITE_DEFAULTS[suite]}
    row = TABLE2.get(name)
    if row is not None:
        lr, freq, feedback, batch, meta, steps = row
        values.update(
            actor_lr=lr,
            critic_lr=lr,
            feedback_frequency=freq,
            max_feedback=feedback,
            reward_batch=batch,
            meta_update_frequency=meta,
            steps=steps,
        )
    return values
