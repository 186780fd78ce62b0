"""The first captured update, checked against the eager update on the same batch.

A CUDA graph replays whatever it recorded, so a capture that went wrong (an op that cannot
be captured, a tensor read at the wrong address, a driver fault) trains silently on garbage.
The fast path therefore runs its first graph replay, then the same update eagerly from the
same state on the same batch and noise, and compares them within the tolerances of the
paths' equivalence tests (tests/agents/test_sac_paths.py): losses within 1% and the weights'
steps pointing the same way (cosine similarity at least 0.98). A failure or a mismatch is
reported as one line; the caller then continues eager.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import torch

LOSS_TOLERANCE = 1e-2  # relative, as bf16 and TF32 are held to against fp32
MIN_STEP_COSINE = 0.98


@dataclass(frozen=True)
class UpdateProbe:
    """What the check needs of an agent, without knowing the agent.

    Attributes:
        captured: capture the update (the first time) and replay it once.
        eager: the same update run eagerly, on the inputs the replay used.
        state: every tensor an update changes (weights, optimiser state, metrics).
        weights: the trained weights, whose steps are compared.
        losses: the last update's losses, read back.
    """

    captured: Callable[[], None]
    eager: Callable[[], None]
    state: Callable[[], list[torch.Tensor]]
    weights: Callable[[], list[torch.Tensor]]
    losses: Callable[[], dict[str, float]]


def check_first_replay(probe: UpdateProbe) -> tuple[str | None, bool]:
    """Run the captured update once and the eager one from the same state.

    Returns:
        (None, True) when they agree; (what differs, True) when they do not, the agent then
        holding the eager update's result; (what failed, False) when the capture or replay
        raised, the agent then as it was before (no update made).
    """
    start = [t.detach().clone() for t in probe.state()]
    before = [w.detach().clone() for w in probe.weights()]
    try:
        probe.captured()
        _synchronize(before)
    except Exception as error:  # any failure of capture or replay means: run eager
        _restore(probe, start)
        return f"the captured update failed ({type(error).__name__}: {_one_line(error)})", False
    replayed = [w.detach().clone() for w in probe.weights()]
    replayed_losses = probe.losses()
    _restore(probe, start)
    probe.eager()
    return _difference(before, replayed, probe.weights(), replayed_losses, probe.losses()), True


def _difference(
    before: list[torch.Tensor],
    replayed: list[torch.Tensor],
    eager: list[torch.Tensor],
    replayed_losses: dict[str, float],
    eager_losses: dict[str, float],
) -> str | None:
    for name, expected in eager_losses.items():
        got = replayed_losses[name]
        allowed = LOSS_TOLERANCE * max(abs(expected), 1e-8)
        if not math.isfinite(got) or abs(got - expected) > allowed:
            return f"its {name} was {got:.6g} where the eager update gives {expected:.6g}"
    cosine = float(
        torch.nn.functional.cosine_similarity(_step(replayed, before), _step(eager, before), dim=0)
    )
    if not math.isfinite(cosine) or cosine < MIN_STEP_COSINE:
        return f"its weight step points elsewhere than the eager one's (cosine {cosine:.3f})"
    return None


def _step(after: list[torch.Tensor], before: list[torch.Tensor]) -> torch.Tensor:
    steps = [(a.detach() - b).flatten().float() for a, b in zip(after, before, strict=True)]
    return torch.cat(steps)


@torch.no_grad()
def _restore(probe: UpdateProbe, saved: list[torch.Tensor]) -> None:
    for tensor, value in zip(probe.state(), saved, strict=True):
        tensor.copy_(value)


def _synchronize(tensors: list[torch.Tensor]) -> None:
    """Surface an asynchronous CUDA error here, inside the check."""
    if tensors and tensors[0].device.type == "cuda":
        torch.cuda.synchronize(tensors[0].device)


def _one_line(error: Exception) -> str:
    text = str(error).strip().splitlines()
    return text[0][:200] if text else "no message"
