"""What a SAC agent is given: its settings (sizes and the update's constants) and how its
update runs (`Execution`). Both take keywords only: nine numbers or six flags in a row
cannot be told apart at the call."""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch


@dataclass(frozen=True, kw_only=True)
class SACSettings:
    """SAC's sizes and constants, named as the run's settings (`TrainConfig`) name them."""

    hidden: int
    layers: int
    actor_lr: float
    critic_lr: float
    alpha_lr: float
    init_temperature: float
    discount: float
    tau: float
    target_update_every: int

    @classmethod
    def from_config(cls, config: object) -> SACSettings:
        """The settings of the same names read from a run's config (or anything that has
        them as attributes)."""
        return cls(**{field.name: getattr(config, field.name) for field in fields(cls)})


@dataclass(frozen=True, kw_only=True)
class Execution:
    """How the update runs; the arithmetic is the same. The defaults are the reference:
    two `nn.Linear` critics, plain Adam, noise from the run's generator, strict fp32."""

    stacked_critics: bool = False
    fused_adam: bool = False
    device_noise: bool = False  # on CUDA only; a CPU run draws from the run's generator
    graphs: bool = False  # CUDA only: replay the update from a captured graph
    precision: str = "fp32"
    flat: bool = False  # CPU: flat buffers and a hand-written backward (`flat_update`)

    @classmethod
    def fast(cls, device: torch.device, precision: str) -> Execution:
        """The fast path: on CUDA autograd's update on the device, captured in a graph; on
        a CPU the flat update."""
        cuda = device.type == "cuda"
        return cls(
            stacked_critics=True,
            fused_adam=True,
            device_noise=cuda,
            graphs=cuda,
            precision=precision,
            flat=not cuda,
        )
