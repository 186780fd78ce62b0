"""The rewards IQL trains on: the dataset's own (the true-reward ceiling) or a learned
model's, scaled as the published IQL setups scale them.

- returns (IQL's D4RL locomotion, `train_offline.py` `normalize`): every reward times
  1000 / (the best episode's return - the worst's), so the spread of returns, not the
  task's units, sets how large advantages and the weights exp(beta A) get;
- unit (LiRE on Meta-World, `algorithms/iql.py` `modify_reward`): each reward mapped by
  the dataset's min and max onto [0, 1]; a learned reward has no units of its own, and this
  gives it the true reward's range on every task.
`auto` takes unit on Meta-World, where LiRE's published numbers live, and returns elsewhere
(DMControl and Gymnasium tasks are locomotion-like).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from seqrank.offline.dataset import OfflineDataset
from seqrank.offline.settings import OfflineConfig, OfflineReward, RewardScale


def resolve_scale(scale: str, task: str) -> RewardScale:
    chosen = RewardScale(scale)
    if chosen is not RewardScale.AUTO:
        return chosen
    from seqrank.envs import canonical_task

    return RewardScale.UNIT if canonical_task(task)[0] == "metaworld" else RewardScale.RETURNS


def scale_rewards(rewards: np.ndarray, starts: np.ndarray, scale: RewardScale) -> np.ndarray:
    """The rewards scaled (float32); a dataset whose returns (or rewards) are all equal is
    left unscaled, there being no spread to scale by."""
    rewards = np.asarray(rewards, np.float64)
    if scale is RewardScale.RETURNS:
        returns = np.add.reduceat(rewards, starts)
        spread = float(returns.max() - returns.min())
        scaled = rewards * (1000.0 / spread) if spread > 0 else rewards
    elif scale is RewardScale.UNIT:
        spread = float(rewards.max() - rewards.min())
        scaled = (rewards - rewards.min()) / spread if spread > 0 else rewards
    elif scale is RewardScale.NONE:
        scaled = rewards
    else:
        raise ValueError(f"resolve {scale} against the task first (resolve_scale)")
    return scaled.astype(np.float32)


LEARNED_REWARDS = "learned_rewards.npy"  # in the run directory: a resumed run reads them
LABELS = "labels.jsonl"  # the labels asked for the learned reward (the label file format)


def training_rewards(
    config: OfflineConfig, dataset: OfflineDataset, folder: Path
) -> tuple[np.ndarray, dict[str, Any] | None]:
    """The per-step rewards before scaling, and for a learned reward the `feedback` row
    that describes its labels and fit. A learned reward is computed once and kept in the
    run directory (`LEARNED_REWARDS`), so a resumed run trains on the same numbers."""
    if config.reward == OfflineReward.TRUE:
        return dataset.rewards.astype(np.float32), None
    kept = folder / LEARNED_REWARDS
    if kept.is_file():
        return np.load(kept), None
    rewards, row = learned_rewards(config, dataset, folder)
    partial = kept.with_name("learned_rewards.part.npy")
    np.save(partial, rewards)
    os.replace(partial, kept)
    return rewards, row


def learned_rewards(
    config: OfflineConfig, dataset: OfflineDataset, folder: Path
) -> tuple[np.ndarray, dict[str, Any]]:
    """The learned reward's seam: `config.max_feedback` questions of `config.scheme` about
    the dataset's segments, answered by `config.teacher` (`offline.labelling`), saved as
    `labels.jsonl`; the reward ensemble fit to the labels and every transition relabelled
    by its mean. Returns the rewards and a `feedback` row."""
    from seqrank.offline.labelling import fit_reward, label_dataset, relabel, save_labels

    labels = label_dataset(
        dataset,
        config.scheme,
        config.teacher,
        config.max_feedback,
        config.session_questions,
        config.segment_length,
        config.seed,
    )
    save_labels(
        labels, dataset, folder / LABELS, config.scheme, config.teacher, config.segment_length
    )
    rewards = relabel(dataset, fit_reward(dataset, labels, seed=config.seed)).rewards
    true = dataset.rewards.astype(np.float64)
    spread = rewards.std() > 0 and true.std() > 0
    row = {
        "kind": "feedback",
        "questions": len(labels.asked),
        "inferred": int(sum(labels.inferred)),
        "total_pairs": len(labels),
        # Pearson, learned against true per-step reward over the whole dataset
        "reward_correlation": float(np.corrcoef(rewards, true)[0, 1]) if spread else 0.0,
    }
    return rewards, row


def check_learned_budget(config: OfflineConfig, dataset: OfflineDataset) -> None:
    """A ValueError, before anything is written, when the learned reward's questions need
    more segments than the dataset holds, or a replayed label file was recorded on another
    task or on steps of another width (`check_replayed`)."""
    if config.reward != OfflineReward.LEARNED:
        return
    from seqrank.feedback.teachers import parse_teacher
    from seqrank.offline.labelling import check_budget

    check_replayed(config, dataset)
    spec = parse_teacher(config.teacher)
    crowd = len(spec.members) if spec.kind == "crowd" else 0
    check_budget(
        dataset,
        config.scheme,
        config.max_feedback,
        config.session_questions,
        config.segment_length,
        crowd,
    )


def check_replayed(config: OfflineConfig, dataset: OfflineDataset) -> None:
    """A `replay:FILE` teacher's labels are of the dataset's task (any spelling of it) and
    their steps of its width, as online `train` and `reward-bench score` require."""
    from seqrank.envs import same_task
    from seqrank.feedback.replay import ReplaySource
    from seqrank.feedback.teachers import parse_teacher

    file = parse_teacher(config.teacher).replay_file
    if file is None:
        return
    source = ReplaySource.from_file(file)
    recorded = source.labels.header.get("task")
    if recorded is not None and not same_task(recorded, dataset.task):
        raise ValueError(
            f"label file {file} was recorded on {recorded}, not on the dataset's task "
            f"{dataset.task}: replay labels of this task, or give a dataset of {recorded}"
        )
    source.check_compatible(dataset.task, dataset.obs_dim, dataset.act_dim)
