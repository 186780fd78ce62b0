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


def scale_for_device(device: str) -> str:
    """`resolve_scale` for a device setting (auto, cpu, cuda), before any device is made."""
    import torch

    cuda = device == "cuda" or (device == "auto" and torch.cuda.is_available())
    return "paper" if cuda else "small"
