"""Soft actor-critic in one folder, as Acme keeps an agent: the agent (`agent`), what it is
given (`settings`), its networks and critics, its checkpoint (`state`), the flat update
of the fast path on a CPU (`flat_update`, `flat_buffers`, `flat_backward`), CUDA graphs
and their check (`cuda_graph`, `graph_check`) and precision contexts (`precision`)."""

from seqrank.agents.sac.agent import SAC, critic_loss
from seqrank.agents.sac.settings import Execution, SACSettings

__all__ = ["SAC", "Execution", "SACSettings", "critic_loss"]
