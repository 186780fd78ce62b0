"""Environments: DMControl, Meta-World and the block-placing task behind one `make_env`."""

from seqrank.envs.base import SimEnv
from seqrank.envs.suites import PAPER_TASKS, canonical_task, make_env, same_task

__all__ = ["PAPER_TASKS", "SimEnv", "canonical_task", "make_env", "same_task"]
