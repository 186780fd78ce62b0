"""What SAC is given: keywords only (nine numbers or six flags in a row cannot be told
apart), and its settings read from a run's config by their names."""

from __future__ import annotations

from dataclasses import fields, replace

import pytest
import torch

from seqrank.agents.sac import Execution, SACSettings
from seqrank.config import TrainConfig
from seqrank.training.cpu_path import UpdateShape, timed_settings


def test_settings_and_execution_take_keywords_only():
    with pytest.raises(TypeError):
        Execution(True, True)  # type: ignore[misc]
    with pytest.raises(TypeError):
        SACSettings(256, 2, 3e-4, 3e-4, 1e-4, 0.1, 0.99, 0.005, 2)  # type: ignore[misc]


def test_sac_settings_are_read_from_the_run_config_by_name():
    config = replace(TrainConfig(), hidden=64, critic_lr=1e-3, target_update_every=3)
    settings = SACSettings.from_config(config)
    assert all(getattr(settings, f.name) == getattr(config, f.name) for f in fields(settings))
    assert (settings.hidden, settings.critic_lr, settings.target_update_every) == (64, 1e-3, 3)


def test_the_cpu_path_times_a_default_runs_sac_at_the_shapes_sizes():
    shape = UpdateShape(obs_dim=24, act_dim=6, hidden=512, layers=3, batch=256)
    expected = replace(SACSettings.from_config(TrainConfig()), hidden=512, layers=3)
    assert timed_settings(shape) == expected


def test_the_fast_path_is_the_flat_update_on_a_cpu_and_graphs_on_cuda():
    assert Execution.fast(torch.device("cpu"), "bf16") == Execution(
        stacked_critics=True, fused_adam=True, precision="bf16", flat=True
    )
    cuda = Execution.fast(torch.device("cuda"), "tf32")
    assert cuda.graphs and cuda.device_noise and not cuda.flat
