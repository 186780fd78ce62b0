"""The global random streams SB3 draws from, saved with the feedback and restored when a
loaded run trains again (SB3's own `load` reseeds them from the model's seed)."""

from __future__ import annotations

import random
from typing import Any

import numpy as np
import torch


def capture_rng(model: Any) -> dict[str, Any]:
    """The global random streams SB3 draws from (and its action space's), so a loaded run
    continues them where the saved one stopped."""
    state = {"torch": torch.get_rng_state(), "numpy": np.random.get_state()}
    state["random"] = random.getstate()
    if model is not None:
        state["action_space"] = model.action_space.np_random.bit_generator.state
    return state


def restore_rng(state: dict[str, Any], model: Any) -> None:
    torch.set_rng_state(state["torch"])
    np.random.set_state(state["numpy"])
    random.setstate(state["random"])
    if "action_space" in state:
        model.action_space.np_random.bit_generator.state = state["action_space"]
