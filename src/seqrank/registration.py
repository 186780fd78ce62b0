"""seqrank's tasks as Gymnasium environments: `gymnasium.make("seqrank/walker_walk-v0",
render_mode="rgb_array")` after `import seqrank` (or, with only gymnasium imported,
`gymnasium.make("seqrank:seqrank/walker_walk-v0")`, which imports seqrank first).

`import seqrank` does not import Gymnasium (about 90 ms): it registers the ids at once when
Gymnasium is imported already, else right after Gymnasium's first import
(`register_on_import`).

Ids: `seqrank/<domain>_<task>-v0` for every DMControl task, `seqrank/<name>-v3` for every
Meta-World v3 MT1 task, `seqrank/block-place-v0`. The names are those of the pinned
dm-control and metaworld (a test compares them with the installed suites); listing them
here keeps `import seqrank` free of the simulators.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import sys
from importlib.machinery import ModuleSpec
from types import ModuleType
from typing import Any

NAMESPACE = "seqrank"
ENTRY_POINT = "seqrank.envs.gymnasium_task:make_task"

DMC_TASKS = (
    "acrobot_swingup",
    "acrobot_swingup_sparse",
    "ball_in_cup_catch",
    "cartpole_balance",
    "cartpole_balance_sparse",
    "cartpole_swingup",
    "cartpole_swingup_sparse",
    "cartpole_three_poles",
    "cartpole_two_poles",
    "cheetah_run",
    "dog_fetch",
    "dog_run",
    "dog_stand",
    "dog_trot",
    "dog_walk",
    "finger_spin",
    "finger_turn_easy",
    "finger_turn_hard",
    "fish_swim",
    "fish_upright",
    "hopper_hop",
    "hopper_stand",
    "humanoid_CMU_run",
    "humanoid_CMU_stand",
    "humanoid_CMU_walk",
    "humanoid_run",
    "humanoid_run_pure_state",
    "humanoid_stand",
    "humanoid_walk",
    "lqr_lqr_2_1",
    "lqr_lqr_6_2",
    "manipulator_bring_ball",
    "manipulator_bring_peg",
    "manipulator_insert_ball",
    "manipulator_insert_peg",
    "pendulum_swingup",
    "point_mass_easy",
    "point_mass_hard",
    "quadruped_escape",
    "quadruped_fetch",
    "quadruped_run",
    "quadruped_walk",
    "reacher_easy",
    "reacher_hard",
    "stacker_stack_2",
    "stacker_stack_4",
    "swimmer_swimmer15",
    "swimmer_swimmer6",
    "walker_run",
    "walker_stand",
    "walker_walk",
)
METAWORLD_TASKS = (
    "assembly-v3",
    "basketball-v3",
    "bin-picking-v3",
    "box-close-v3",
    "button-press-topdown-v3",
    "button-press-topdown-wall-v3",
    "button-press-v3",
    "button-press-wall-v3",
    "coffee-button-v3",
    "coffee-pull-v3",
    "coffee-push-v3",
    "dial-turn-v3",
    "disassemble-v3",
    "door-close-v3",
    "door-lock-v3",
    "door-open-v3",
    "door-unlock-v3",
    "drawer-close-v3",
    "drawer-open-v3",
    "faucet-close-v3",
    "faucet-open-v3",
    "hammer-v3",
    "hand-insert-v3",
    "handle-press-side-v3",
    "handle-press-v3",
    "handle-pull-side-v3",
    "handle-pull-v3",
    "lever-pull-v3",
    "peg-insert-side-v3",
    "peg-unplug-side-v3",
    "pick-out-of-hole-v3",
    "pick-place-v3",
    "pick-place-wall-v3",
    "plate-slide-back-side-v3",
    "plate-slide-back-v3",
    "plate-slide-side-v3",
    "plate-slide-v3",
    "push-back-v3",
    "push-v3",
    "push-wall-v3",
    "reach-v3",
    "reach-wall-v3",
    "shelf-place-v3",
    "soccer-v3",
    "stick-pull-v3",
    "stick-push-v3",
    "sweep-into-v3",
    "sweep-v3",
    "window-close-v3",
    "window-open-v3",
)


def gymnasium_ids() -> dict[str, str]:
    """Gymnasium id -> seqrank task name."""
    ids = {f"{NAMESPACE}/{name}-v0": f"dmc:{name}" for name in DMC_TASKS}
    ids |= {f"{NAMESPACE}/{name}": f"metaworld:{name}" for name in METAWORLD_TASKS}
    ids[f"{NAMESPACE}/block-place-v0"] = "block:place"
    return ids


def register_tasks() -> None:
    """Register every id with Gymnasium (once: an id already there is left alone)."""
    import gymnasium

    for env_id, task in gymnasium_ids().items():
        if env_id not in gymnasium.registry:
            gymnasium.register(env_id, entry_point=ENTRY_POINT, kwargs={"task": task})


def register_on_import() -> None:
    """Register the ids now if Gymnasium is imported, else once it is (a finder on
    `sys.meta_path` that runs `register_tasks` after Gymnasium's module has run)."""
    if "gymnasium" in sys.modules:
        register_tasks()
    elif not any(isinstance(finder, _AfterGymnasium) for finder in sys.meta_path):
        sys.meta_path.insert(0, _AfterGymnasium())


class _AfterGymnasium(importlib.abc.MetaPathFinder):
    """Finds Gymnasium as the other finders do, its loader wrapped to register the ids."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> ModuleSpec | None:
        if name != "gymnasium":
            return None
        sys.meta_path.remove(self)  # once, and not for the search below
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.loader is not None:
            spec.loader = _ThenRegister(spec.loader)
        return spec


class _ThenRegister(importlib.abc.Loader):
    """Gymnasium's own loader, then `register_tasks`; anything else asked of it (resource
    readers, ...) is the wrapped loader's."""

    def __init__(self, loader: importlib.abc.Loader):
        self.loader = loader

    def create_module(self, spec: ModuleSpec) -> ModuleType | None:
        return self.loader.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        self.loader.exec_module(module)
        register_tasks()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.loader, name)
