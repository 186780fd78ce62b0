"""The flat update's storage: each network's weights in one flat buffer that its modules'
parameters view, its Adam on that buffer, and the check that the views still hold.

The parameters are views of the flat buffers (`flatten`); the flat update reads and steps
the buffers, never the parameters. Anything that gives a parameter other storage unhooks
its module from the update without an error: the update would go on training the buffer
while the module (acting, checkpoints, evaluation) kept the stale copy. That includes
assigning `param.data`, assigning a new `nn.Parameter`, `load_state_dict(..., assign=True)`,
and `.to()` / `.half()` / `.double()` into another device or dtype. Weights go in by
copying (`param.copy_`, a plain `load_state_dict`), which every loader here does;
`FlatViews.check` is run after every load and critic reset to say so if that ever changes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import torch
from torch import nn
from torch.optim.adam import adam

NamedTensors = Callable[[], Iterable[tuple[str, torch.Tensor]]]


def flatten(params: Sequence[nn.Parameter], flat: torch.Tensor) -> None:
    """Copies `params` into `flat` and makes each parameter a view of its slice."""
    offset = 0
    with torch.no_grad():
        for param in params:
            view = flat[offset : offset + param.numel()].view_as(param)
            view.copy_(param)
            param.data = view
            offset += param.numel()


def views(flat: torch.Tensor, like: Sequence[torch.Tensor]) -> list[torch.Tensor]:
    """`flat` cut into tensors shaped as `like`, in order."""
    sizes = [t.numel() for t in like]
    return [part.view_as(t) for part, t in zip(flat.split(sizes), like, strict=True)]


@dataclass(frozen=True)
class FlatViews:
    """Where a module's parameters must stay: each one's address in its flat buffer."""

    name: str  # the agent's attribute, for the error: "actor", "critic", ...
    parameters: NamedTensors  # the module's, as they are now
    addresses: tuple[int, ...]

    @classmethod
    def of(cls, name: str, parameters: NamedTensors) -> FlatViews:
        """The addresses the parameters have now (call it right after `flatten`)."""
        return cls(name, parameters, tuple(p.data_ptr() for _, p in parameters()))

    def check(self) -> None:
        """Raises RuntimeError naming the first parameter that no longer views its slice."""
        current = list(self.parameters())
        if len(current) != len(self.addresses):
            raise RuntimeError(self._unhooked(f"now has {len(current)} parameters"))
        for (name, param), address in zip(current, self.addresses, strict=True):
            if param.data_ptr() != address:
                raise RuntimeError(self._unhooked(f"parameter {name!r} no longer views it"))

    def _unhooked(self, what: str) -> str:
        return (
            f"the flat update trains its {self.name}'s weights in a flat buffer, and the "
            f"{self.name} {what} (its .data was reassigned, a parameter replaced or the module "
            "moved to another dtype or device): the update would train weights the module "
            "no longer uses. Copy weights in place instead (param.copy_, load_state_dict "
            "without assign=True; agents.sac.flat_buffers)"
        )


class FlatNet:
    """A network's weights flattened: fp32 master copy, a copy in the compute precision and
    its gradient buffer (the same tensors as the fp32 ones when computing in fp32)."""

    def __init__(self, master: torch.Tensor, params: Sequence[torch.Tensor], dtype: torch.dtype):
        self.master, self.params = master, params
        low = dtype != master.dtype
        self.compute = torch.empty_like(master, dtype=dtype) if low else master
        self.compute_views = views(self.compute, params)

    def cast(self, size: int | None = None) -> None:
        """The compute copy brought up to date (its first `size` values only, if given)."""
        if self.compute is not self.master:
            self.compute[:size].copy_(self.master[:size])


class FlatAdam:
    """Adam (torch's fused kernel) on one flat parameter buffer, its state recorded in a
    `torch.optim.Adam` as views, so checkpoints and resets see one state."""

    def __init__(self, optimizer: torch.optim.Adam, flat: torch.Tensor):
        self.optimizer, self.flat = optimizer, flat
        self.params: list[torch.Tensor] = list(optimizer.param_groups[0]["params"])
        self.grad = torch.zeros_like(flat)
        self.exp_avg, self.exp_avg_sq = torch.zeros_like(flat), torch.zeros_like(flat)
        self.steps = torch.zeros((), dtype=torch.float32)
        self._recorded: torch.Tensor | None = None  # the first parameter's recorded moment
        optimizer.step = _stepped_elsewhere  # type: ignore[method-assign]

    def adopt(self) -> None:
        """Takes the optimiser's recorded state (after a load) into the flat buffers; an
        empty record stays empty until the first step, as with torch's Adam."""
        state = self.optimizer.state
        if not state:
            return
        with torch.no_grad():
            for moment in ("exp_avg", "exp_avg_sq"):
                values = [state[p][moment].clone() for p in self.params]
                for view, value in zip(
                    views(getattr(self, moment), self.params), values, strict=True
                ):
                    view.copy_(value)
            self.steps.copy_(state[self.params[0]]["step"])
        self._record()

    def _record(self) -> None:
        moments = views(self.exp_avg, self.params), views(self.exp_avg_sq, self.params)
        for param, avg, avg_sq in zip(self.params, *moments, strict=True):
            self.optimizer.state[param] = {"step": self.steps, "exp_avg": avg, "exp_avg_sq": avg_sq}
        self._recorded = self.optimizer.state[self.params[0]]["exp_avg"]

    def step(self) -> None:
        """One Adam step on `grad` (fresh state on the first step or after a reset; a
        record replaced behind its back, e.g. by the optimiser's own `load_state_dict`,
        is taken in first)."""
        state = self.optimizer.state
        if not state:
            self.exp_avg.zero_()
            self.exp_avg_sq.zero_()
            self.steps.zero_()
            self._record()
        elif state.get(self.params[0], {}).get("exp_avg") is not self._recorded:
            self.adopt()
        group = self.optimizer.param_groups[0]
        beta1, beta2 = group["betas"]
        adam(
            [self.flat], [self.grad], [self.exp_avg], [self.exp_avg_sq], [], [self.steps],
            fused=True, amsgrad=False, beta1=beta1, beta2=beta2, lr=group["lr"],
            weight_decay=group["weight_decay"], eps=group["eps"], maximize=False,
        )  # fmt: skip


def _stepped_elsewhere(*args: object, **kwargs: object) -> None:
    raise RuntimeError(
        "this optimiser only records the Adam state of a flat update "
        "(seqrank.agents.sac.flat_update), which steps the weights itself; stepping it "
        "too would move them twice"
    )
