"""`block:place`: the paper's real-robot task (supplementary D.1) as a simulated tabletop.

A kinematic model, not MuJoCo physics: the block moves exactly 5 cm per action, as the
UR-5 pushes in the paper are specified, so contact dynamics would add nothing but noise.

Geometry (metres; x to the right along the 70 cm side, y up along the 60 cm side, as seen
from above): the block is a 4 cm square; its centre always stays on the table, at least
half a block from every edge. Each episode starts with the centre drawn uniformly in the
20 x 20 cm square at the top-left corner (x in [0.02, 0.22], y in [0.38, 0.58]). The goal
is fixed near the bottom-right corner at (0.62, 0.08). Action k of 8 moves the block 5 cm
in direction k * pi/4 (0 right, 2 up, 4 left, 6 down); a push past the table edge stops at
the edge (the move is clipped per axis). Success: the centre within 3 cm of the goal. Once
placed, the block stays put (later pushes do nothing) and the episode runs on to its limit
of 50 steps, so every episode has the same length and yields 30-step segments.

Observation (5 floats): 10 x (x, y, goal_x - x, goal_y - y) (decimetres) and 1.0 once
placed. True reward per step: -10 x distance to the goal (0 once placed); it drives the
scripted teachers and evaluation, never the agent. The action given to `step` is 8 scores
(a one-hot from the agent; any vector works): the highest score is the direction.

Robot seam: the environment talks to a `BlockDriver`, whose contract is below. The
simulator's `KinematicDriver` is the default; a real robot driver (camera-measured block
position, arm pushes) implements the same three calls and the rest is unchanged. Saved
states and clips (re-rendering) then come from the measured positions.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from seqrank.envs.base import SimEnv

TABLE_WIDTH, TABLE_DEPTH = 0.70, 0.60  # x, y extent in metres
BLOCK_HALF = 0.02
START_LOW = np.array([BLOCK_HALF, TABLE_DEPTH - BLOCK_HALF - 0.20])  # 20 x 20 cm square
START_SIZE = 0.20
GOAL = np.array([0.62, 0.08])
PUSH = 0.05
SUCCESS_RADIUS = 0.03
EPISODE_STEPS = 50
DIRECTIONS = 8


class BlockDriver(Protocol):
    """What moves the block and reports where it is (metres, table frame above)."""

    def place(self, position: np.ndarray) -> np.ndarray:
        """Put the block at `position` (start of an episode); return the measured position."""
        ...

    def push(self, direction: int) -> np.ndarray:
        """Push the block 5 cm in direction `direction` * pi/4; return the measured position."""
        ...

    def close(self) -> None: ...


class KinematicDriver:
    """The simulated table: exact 5 cm moves, clipped at the edges."""

    def __init__(self) -> None:
        self.position = START_LOW + START_SIZE / 2

    def place(self, position: np.ndarray) -> np.ndarray:
        self.position = clip_to_table(np.asarray(position, np.float64))
        return self.position.copy()

    def push(self, direction: int) -> np.ndarray:
        angle = direction * math.pi / 4
        step = PUSH * np.array([math.cos(angle), math.sin(angle)])
        self.position = clip_to_table(self.position + step)
        return self.position.copy()

    def close(self) -> None:
        pass


def clip_to_table(position: np.ndarray) -> np.ndarray:
    low = np.array([BLOCK_HALF, BLOCK_HALF])
    high = np.array([TABLE_WIDTH - BLOCK_HALF, TABLE_DEPTH - BLOCK_HALF])
    clipped: np.ndarray = np.clip(position, low, high)
    return clipped


class BlockPlaceEnv(SimEnv):
    """gymnasium semantics like the other tasks; `discrete` tells the trainer to use DQN."""

    discrete = True

    def __init__(self, seed: int = 0, driver: BlockDriver | None = None):
        self.name = "block:place"
        self.episode_length = EPISODE_STEPS
        self.driver: BlockDriver = driver if driver is not None else KinematicDriver()
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (5,), np.float32)
        self.action_space = gym.spaces.Box(0.0, 1.0, (DIRECTIONS,), np.float32)
        self._rng = np.random.default_rng(seed)
        self.position = START_LOW + START_SIZE / 2
        self.placed = False
        self.t = 0

    # ---- gymnasium -----------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        start = START_LOW + self._rng.uniform(0.0, START_SIZE, 2)
        self.position = self.driver.place(start)
        self.placed, self.t = False, 0
        self._check_placed()
        return self._obs(), {"success": self.placed}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        direction = direction_of(action)
        if not self.placed:
            self.position = self.driver.push(direction)
            self._check_placed()
        self.t += 1
        reward = 0.0 if self.placed else -10.0 * self.distance
        truncated = self.t >= EPISODE_STEPS
        return self._obs(), reward, False, truncated, {"success": self.placed}

    @property
    def distance(self) -> float:
        return float(np.linalg.norm(self.position - GOAL))

    def _check_placed(self) -> None:
        self.placed = self.placed or self.distance <= SUCCESS_RADIUS

    def _obs(self) -> np.ndarray:
        x, y = self.position
        offset = GOAL - self.position
        return np.array(
            [10 * x, 10 * y, 10 * offset[0], 10 * offset[1], float(self.placed)], np.float32
        )

    def canonical_action(self, action: np.ndarray) -> np.ndarray:
        return one_hot(direction_of(action))

    # ---- state and pictures ----------------------------------------------------------
    def get_state(self) -> np.ndarray:
        return np.array([*self.position, float(self.placed), float(self.t)])

    def set_state(self, state: np.ndarray) -> None:
        """Put the block where `state` says (a robot driver moves the real block there)."""
        self.position = self.driver.place(np.asarray(state[:2], np.float64))
        self.placed, self.t = bool(state[2]), int(state[3])

    def use_fast_rendering(self) -> None:
        """The drawing is already cheap."""

    def render_frame(self, width: int = 128, height: int = 128) -> np.ndarray:
        return draw_table(self.position, self.placed, width, height)

    def render_states(
        self, states: np.ndarray, context: int | None = None, width: int = 128, height: int = 128
    ) -> np.ndarray:
        return np.stack([draw_table(s[:2], bool(s[2]), width, height) for s in states])

    def close(self) -> None:
        self.driver.close()


def direction_of(action: np.ndarray | int) -> int:
    if np.ndim(action) == 0:
        direction = int(action)
        if not 0 <= direction < DIRECTIONS:
            raise ValueError(f"direction {direction}: accepted 0..{DIRECTIONS - 1}")
        return direction
    scores = np.asarray(action).reshape(-1)
    if scores.shape != (DIRECTIONS,):
        raise ValueError(f"block:place takes {DIRECTIONS} action scores, got shape {scores.shape}")
    return int(np.argmax(scores))


def one_hot(direction: int) -> np.ndarray:
    vector = np.zeros(DIRECTIONS, np.float32)
    vector[direction] = 1.0
    return vector


# colours (RGB)
_FLOOR, _TABLE, _START = (40, 44, 52), (205, 170, 125), (150, 180, 220)
_GOAL, _BLOCK, _PLACED = (60, 170, 90), (200, 50, 40), (30, 120, 60)


def draw_table(position: np.ndarray, placed: bool, width: int, height: int) -> np.ndarray:
    """A top-down picture: table, start square, goal zone (3 cm) and the block."""
    margin = 0.03
    scale = min(width / (TABLE_WIDTH + 2 * margin), height / (TABLE_DEPTH + 2 * margin))
    cols = (np.arange(width) + 0.5 - width / 2) / scale + TABLE_WIDTH / 2
    rows = TABLE_DEPTH / 2 - (np.arange(height) + 0.5 - height / 2) / scale
    x, y = np.meshgrid(cols, rows)
    frame = np.empty((height, width, 3), np.uint8)
    frame[:] = _FLOOR
    on_table = (x >= 0) & (x <= TABLE_WIDTH) & (y >= 0) & (y <= TABLE_DEPTH)
    frame[on_table] = _TABLE
    start_high = START_LOW + START_SIZE
    in_start = (x >= START_LOW[0] - BLOCK_HALF) & (x <= start_high[0] + BLOCK_HALF)
    in_start &= (y >= START_LOW[1] - BLOCK_HALF) & (y <= start_high[1] + BLOCK_HALF)
    frame[in_start & on_table] = _START
    goal_distance = np.hypot(x - GOAL[0], y - GOAL[1])
    frame[goal_distance <= SUCCESS_RADIUS] = _GOAL
    block = (np.abs(x - position[0]) <= BLOCK_HALF) & (np.abs(y - position[1]) <= BLOCK_HALF)
    frame[block] = _PLACED if placed else _BLOCK
    return frame
