"""`seqrank dataset make` and `load_dataset` at their edges: tasks without MuJoCo state,
tasks seqrank cannot play, source shares, non-finite values, foreign action bounds and
the messages of datasets that cannot be read or labelled."""

from __future__ import annotations

import json

from seqrank.cli import main
from seqrank.offline.minari_io import episodes_with_states, load_dataset


def refusal(capsys, *args: str) -> str:
    """The one line a refused command prints (exit code 2)."""
    code = main(list(args))
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    return err


def test_random_play_on_a_task_without_mujoco_state_keeps_no_states(tmp_path, capsys):
    out = tmp_path / "pendulum"
    code = main(["dataset", "make", "--task", "gym:Pendulum-v1", "--source", "random",
                 "--episodes", "2", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    dataset = load_dataset(out)
    assert dataset.episode_count == 2 and dataset.act_dim == 1
    try:
        episodes_with_states(out)
    except ValueError as problem:
        assert "no physics states" in str(problem)
    else:
        raise AssertionError("a dataset without states was taken for labelling")


def test_a_task_with_discrete_actions_is_refused_in_one_line_leaving_nothing(tmp_path, capsys):
    out = tmp_path / "cartpole"
    err = refusal(capsys, "dataset", "make", "--task", "gym:CartPole-v1", "--source",
                  "random", "--episodes", "2", "--out", str(out))  # fmt: skip
    assert "Discrete(2)" in err and "Box" in err
    assert not out.exists()


def test_sources_without_a_share_split_what_the_shares_leave():
    from seqrank.offline.sources import episode_counts, parse_source

    def counts(*texts: str, episodes: int = 10) -> list[int]:
        return episode_counts([parse_source(t) for t in texts], episodes)

    assert counts("scripted=0.7", "random") == [7, 3]
    assert counts("scripted=0.5", "random", "scripted:0.3") == [5, 3, 2]  # ties in order
    assert counts("scripted=0.1", "random=0.2", "scripted:0.3=0.7") == [1, 2, 7]
    assert counts("random", "scripted") == [5, 5]
    for texts, why in (
        (("scripted=0.7", "random=0.5"), "0.7 + 0.5 = 1.2, more than 1"),
        (("scripted=0.7", "random=0.3", "scripted:0"), "leaving nothing"),
        (("scripted=0.4", "random=0.3"), "less than 1, and no source without a share"),
    ):
        try:
            counts(*texts)
        except ValueError as problem:
            assert why in str(problem) and "accepted: shares" in str(problem), problem
        else:
            raise AssertionError(f"{texts} were taken")


def test_shares_that_do_not_add_up_are_refused_by_dataset_make(tmp_path, capsys):
    err = refusal(capsys, "dataset", "make", "--task", "dmc:cartpole_swingup", "--source",
                  "random=0.4", "--source", "random=0.3", "--episodes", "10",
                  "--out", str(tmp_path / "d"))  # fmt: skip
    assert "0.4 + 0.3 = 0.7, less than 1" in err and not (tmp_path / "d").exists()


def _minari_dataset(folder, rewards, low=-1.0, high=1.0, env_id="seqrank/cartpole_swingup-v0"):
    """A dataset of one 10-step cartpole_swingup episode, written by Minari's own API."""
    import gymnasium
    import numpy as np
    from minari.data_collector.episode_buffer import EpisodeBuffer
    from minari.dataset.minari_storage import MinariStorage

    import seqrank  # noqa: F401  (registers the seqrank/ ids)

    folder.mkdir()
    spaces = {
        "observation_space": gymnasium.spaces.Box(-np.inf, np.inf, (5,), np.float32),
        "action_space": gymnasium.spaces.Box(low, high, (1,), np.float32),
    }
    spec = gymnasium.spec(env_id) if env_id else None
    storage = MinariStorage.new(folder / "data", env_spec=spec, **spaces)
    storage.update_metadata({"dataset_id": "foreign-v0", "minari_version": "0.5.4"})
    rng = np.random.default_rng(0)
    actions = rng.uniform(0, 1, (10, 1)) * (np.asarray(high) - low) + low
    episode = EpisodeBuffer(
        observations=rng.normal(size=(11, 5)).astype(np.float32),
        actions=actions.astype(np.float32),
        rewards=list(rewards),
        terminations=[False] * 9 + [True],
        truncations=[False] * 10,
    )
    storage.update_episodes([episode])
    return folder


def test_a_non_finite_reward_is_refused_in_one_line_by_every_command_that_loads_it(
    tmp_path, capsys
):
    data = str(_minari_dataset(tmp_path / "nan", [0.5] * 4 + [float("nan")] + [0.5] * 5))
    why = f"dataset {data}: episode 0 has a non-finite value (NaN or infinity) in its rewards"
    for command in (
        ["dataset", "info", data],
        ["reward-bench", "pool", "--from-dataset", data, "--out", str(tmp_path / "p.npz")],
        ["offline", "train", "--dataset", data, "--out", str(tmp_path / "run"), "--quiet"],
        ["label", "offline", "--dataset", data, "--out", str(tmp_path / "labels")],
    ):
        assert why in refusal(capsys, *command), command
    assert not any(p.name != "nan" for p in tmp_path.iterdir())


def test_a_foreign_datasets_action_bounds_are_rescaled_to_minus_one_one(tmp_path, capsys):
    import numpy as np

    wide = load_dataset(_minari_dataset(tmp_path / "wide", [0.5] * 10, -2.0, 2.0))
    # _minari_dataset's first draws, as a fraction of the bounds: [-2, 2] -> [-1, 1]
    expected = np.random.default_rng(0).uniform(0, 1, (10, 1)) * 2 - 1
    np.testing.assert_allclose(wide.actions, expected, atol=1e-6)
    assert wide.meta["actions_rescaled_from"] == {"low": [-2.0], "high": [2.0]}
    unit = load_dataset(_minari_dataset(tmp_path / "unit", [0.5] * 10))
    np.testing.assert_allclose(unit.actions, expected, atol=1e-6)  # left as they are
    assert "actions_rescaled_from" not in unit.meta
    made = tmp_path / "made"  # seqrank's own datasets: Box(-1, 1), read as played
    assert main(["dataset", "make", "--task", "dmc:cartpole_swingup", "--source", "random",
                 "--episodes", "1", "--out", str(made)]) == 0  # fmt: skip
    metadata = json.loads((made / "data" / "metadata.json").read_text())
    assert json.loads(metadata["action_space"])["low"] == [-1.0]
    assert "actions_rescaled_from" not in load_dataset(made).meta
    infinite = str(_minari_dataset(tmp_path / "inf", [0.5] * 10, -np.inf, np.inf))
    err = refusal(capsys, "dataset", "info", infinite)
    assert "without finite bounds" in err and "accepted: Box action spaces" in err


def test_messages_name_what_is_wrong_with_a_dataset(tmp_path, capsys):
    from dataclasses import replace

    import numpy as np

    from seqrank.offline.minari_write import save_episodes
    from seqrank.offline.sources import random_play

    err = refusal(capsys, "dataset", "make", "--task", "dmc:cartpole_swingup", "--source",
                  "random", "--episodes", "1", "--out", "")  # fmt: skip
    assert err.endswith("--out is empty; accepted: a Minari dataset id, (namespace/)name-vN, "
                        "or the path of a dataset folder that does not exist yet")  # fmt: skip
    played = random_play("dmc:cartpole_swingup", 3, np.random.SeedSequence(0))
    mixed = [played[0], *(replace(e, states=None) for e in played[1:])]  # as a run's, some
    save_episodes(mixed, tmp_path / "mixed", "dmc:cartpole_swingup", {}, "mixed")
    try:
        episodes_with_states(tmp_path / "mixed")
    except ValueError as problem:
        assert "holds no physics states in 2 of its 3 episodes" in str(problem), problem
    else:
        raise AssertionError("a dataset with stateless episodes was taken for labelling")
    (tmp_path / "mixed" / "data" / "main_data.hdf5").unlink()
    err = refusal(capsys, "dataset", "info", str(tmp_path / "mixed"))
    assert f"dataset {tmp_path / 'mixed'} has its metadata but not its data file" in err
    unnamed = str(_minari_dataset(tmp_path / "unnamed", [0.5] * 10, env_id=None))
    err = refusal(capsys, "dataset", "info", unnamed)
    assert "records no environment (no environment spec)): name the task" in err
    assert "--task" in err and "None" not in err
