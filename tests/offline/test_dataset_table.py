"""What IQL's batches hold: the dataset's rows, and a bootstrap stopped only at a true
terminal (a time limit is no terminal)."""

from __future__ import annotations

import numpy as np
import torch

from seqrank.offline.dataset import OfflineDataset
from seqrank.offline.train import DatasetTable


def test_not_done_is_zero_only_at_terminations_and_batches_are_the_datasets_rows():
    rows = 6
    observations = np.arange(rows * 2, dtype=np.float32).reshape(rows, 2)
    dataset = OfflineDataset(
        task="support.sb3_envs:make_line",
        observations=observations,
        actions=np.linspace(-1, 1, rows, dtype=np.float32).reshape(rows, 1),
        rewards=np.arange(rows, dtype=np.float32),
        next_observations=observations + 100,
        terminations=np.array([0, 0, 1, 0, 0, 0], bool),  # episode 0 ends in a terminal
        truncations=np.array([0, 0, 0, 0, 0, 1], bool),  # episode 1 by its time limit
        starts=np.array([0, 3]),
    )
    rewards = np.arange(rows, dtype=np.float32) * 10  # the rewards trained on, not the true
    table = DatasetTable(dataset, rewards, torch.device("cpu"))
    np.testing.assert_array_equal(table.not_done[:, 0].numpy(), [1, 1, 0, 1, 1, 1])

    batch = table.sample(50, torch.Generator().manual_seed(0))
    index = batch.obs[:, 0].numpy().astype(int) // 2  # each row's first observation is 2 i
    np.testing.assert_array_equal(batch.next_obs.numpy(), batch.obs.numpy() + 100)
    np.testing.assert_array_equal(batch.reward[:, 0].numpy(), rewards[index])
    np.testing.assert_array_equal(batch.action.numpy(), dataset.actions[index])
    np.testing.assert_array_equal(batch.not_done[:, 0].numpy(), index != 2)
