"""seqrank's tasks as Gymnasium ids (`seqrank/<task>`), registered by `import seqrank`."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import metaworld
import numpy as np
import pytest
from dm_control import suite

import seqrank
from seqrank.registration import DMC_TASKS, METAWORLD_TASKS, gymnasium_ids


def test_every_installed_dmcontrol_and_metaworld_task_has_an_id():
    assert set(DMC_TASKS) == {f"{d}_{t}" for d, t in suite.ALL_TASKS}
    assert set(METAWORLD_TASKS) == set(metaworld.MT1.ENV_NAMES)
    ids = gymnasium_ids()
    assert len(ids) == len(DMC_TASKS) + len(METAWORLD_TASKS) + 1
    assert all(env_id in gym.registry for env_id in ids)
    assert seqrank.__version__


@pytest.mark.parametrize(
    ("env_id", "obs_dim"),
    [("seqrank/walker_walk-v0", 24), ("seqrank/block-place-v0", 5), ("seqrank/reach-v3", 39)],
)
def test_an_id_makes_the_task_with_rgb_frames(env_id, obs_dim):
    env = gym.make(env_id, render_mode="rgb_array", width=64, height=48)
    obs, _ = env.reset(seed=3)
    again, _ = env.reset(seed=3)
    np.testing.assert_array_equal(obs, again)  # an episode is a function of its seed
    assert obs.shape == (obs_dim,) and obs.dtype == np.float32
    _, reward, terminated, _, info = env.step(env.action_space.sample())
    assert isinstance(reward, float) and not terminated and "success" in info
    frame = env.render()
    assert frame.shape == (48, 64, 3) and frame.dtype == np.uint8 and frame.std() > 0
    env.close()
    with pytest.raises(ValueError, match="render_mode 'human'; accepted: rgb_array"):
        gym.make(env_id, render_mode="human")


def test_gymnasium_alone_finds_the_ids_by_module_prefix():
    make = "gymnasium.make('seqrank:seqrank/cartpole_swingup-v0')"
    code = f"import gymnasium; print({make}.reset(seed=0)[0].shape)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.stdout.strip() == "(5,)", done.stderr


def test_a_made_task_names_its_episode_length_in_its_spec():
    """What TimeLimit users (SB3, gymnasium.make(spec)) read; the task truncates there itself."""
    import gymnasium

    import seqrank  # noqa: F401  (registers the ids)

    env = gymnasium.make("seqrank/cartpole_swingup-v0")
    assert env.spec is not None and env.spec.max_episode_steps == 1000
    again = gymnasium.make(env.spec)
    again.reset(seed=0)
    steps, done = 0, False
    while not done:
        _, _, terminated, truncated, _ = again.step(again.action_space.sample())
        steps, done = steps + 1, terminated or truncated
    assert steps == 1000 and again.spec.max_episode_steps == 1000
    env.close()
    again.close()


def test_import_seqrank_leaves_gymnasium_unimported_and_its_import_registers_the_ids():
    light = "import seqrank, sys; assert 'gymnasium' not in sys.modules"
    later = "import gymnasium; print(gymnasium.make('seqrank/cartpole_swingup-v0').spec.id)"
    done = subprocess.run(
        [sys.executable, "-c", f"{light}; {later}"], capture_output=True, text=True
    )
    assert done.stdout.strip() == "seqrank/cartpole_swingup-v0", done.stderr
    first = "import gymnasium, seqrank; print('seqrank/walker_walk-v0' in gymnasium.registry)"
    done = subprocess.run([sys.executable, "-c", first], capture_output=True, text=True)
    assert done.stdout.strip() == "True", done.stderr
