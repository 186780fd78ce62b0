"""SAC's checkpoint in one layout whatever path wrote it.

Critic weights and Adam moments are stored in the canonical (`TwinCritic`) layout and the
Adam step as a number, so a run saved on the fast path resumes on the reference path and
back. Loading copies into the existing tensors, so a captured CUDA graph stays valid.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import torch

from seqrank.agents.sac.critics import Canonical, canonical_weights, load_canonical_weights

LAYOUT = "sac-canonical-1"
MOMENTS = ("exp_avg", "exp_avg_sq")
Named = Callable[[list[torch.Tensor]], Canonical]
Unnamed = Callable[[Canonical], list[torch.Tensor]]


def sac_state(agent: Any) -> dict[str, Any]:
    """Weights, temperature, optimisers and update count of a SAC agent."""
    actor_names = [name for name, _ in agent.actor.named_parameters()]

    def name_actor(tensors: list[torch.Tensor]) -> Canonical:
        return dict(zip(actor_names, tensors, strict=True))

    return {
        "layout": LAYOUT,
        "actor": agent.actor.state_dict(),
        "critic": canonical_weights(agent.critic),
        "critic_target": canonical_weights(agent.critic_target),
        "log_alpha": agent.log_alpha.detach().clone(),
        "updates": agent.updates,
        "actor_opt": _adam_state(agent.actor_opt, name_actor),
        "critic_opt": _adam_state(agent.critic_opt, agent.critic.to_canonical),
        "alpha_opt": _adam_state(agent.alpha_opt, lambda t: {"log_alpha": t[0]}),
    }


def load_sac_state(agent: Any, state: dict[str, Any]) -> None:
    """The inverse of `sac_state`."""
    if state.get("layout") != LAYOUT:
        raise ValueError(
            "this checkpoint's agent was saved by an older seqrank, whose SAC checkpoints "
            "depended on the path (reference or fast); it cannot be resumed by this version: "
            "start the run again (labels exported from it can be replayed with "
            "--teacher replay:FILE)"
        )
    agent.actor.load_state_dict(state["actor"])
    load_canonical_weights(agent.critic, state["critic"])
    load_canonical_weights(agent.critic_target, state["critic_target"])
    with torch.no_grad():
        agent.log_alpha.copy_(state["log_alpha"])
    agent.updates = state["updates"]
    actor_names = [name for name, _ in agent.actor.named_parameters()]
    _load_adam(agent.actor_opt, state["actor_opt"], lambda c: [c[n] for n in actor_names])
    _load_adam(agent.critic_opt, state["critic_opt"], agent.critic.from_canonical)
    _load_adam(agent.alpha_opt, state["alpha_opt"], lambda c: [c["log_alpha"]])


def _params(optimizer: torch.optim.Optimizer) -> list[torch.Tensor]:
    return list(optimizer.param_groups[0]["params"])


def _adam_state(optimizer: torch.optim.Optimizer, named: Named) -> dict[str, Any] | None:
    """Adam's step and moments by canonical name; None before the first step."""
    params = _params(optimizer)
    if not optimizer.state:
        return None
    state: dict[str, Any] = {"step": float(optimizer.state[params[0]]["step"])}
    for moment in MOMENTS:
        tensors = [optimizer.state[p][moment].detach() for p in params]
        state[moment] = {name: t.clone() for name, t in named(tensors).items()}
    return state


@torch.no_grad()
def _load_adam(
    optimizer: torch.optim.Optimizer, state: dict[str, Any] | None, unnamed: Unnamed
) -> None:
    params = _params(optimizer)
    if state is None:
        optimizer.state.clear()
        return
    group = optimizer.param_groups[0]
    on_device = bool(group.get("fused") or group.get("capturable"))
    moments = {moment: unnamed(state[moment]) for moment in MOMENTS}
    for i, param in enumerate(params):
        values = {moment: moments[moment][i].to(param.device) for moment in MOMENTS}
        step = torch.tensor(state["step"], dtype=torch.float32)
        values["step"] = step.to(param.device) if on_device else step
        current = optimizer.state.get(param)
        if current:  # in place: a captured graph reads these addresses
            for key, value in values.items():
                current[key].copy_(value)
        else:
            optimizer.state[param] = {k: v.clone() for k, v in values.items()}
