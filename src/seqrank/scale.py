"""The one place where `--scale auto` becomes a preset name."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # torch loads slowly; callers already hold a device
    import torch


def resolve_scale(scale: str, device: torch.device) -> str:
    """ "paper" (Table 2 sizes) on CUDA, "small" elsewhere; an explicit scale passes through."""
    if scale != "auto":
        return scale
    return "paper" if device.type == "cuda" else "small"
