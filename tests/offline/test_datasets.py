"""`seqrank dataset make|info` and `load_dataset` as a user meets them: datasets made at
tiny sizes, read back by seqrank and by Minari itself, replayed in the task's environment
to the same observations and rewards; a run's episodes as a dataset; foreign datasets."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium
import numpy as np
import pytest

from seqrank.cli import main
from seqrank.envs import make_env
from seqrank.offline.minari_io import episode_successes, load_dataset

CARTPOLE = "dmc:cartpole_swingup"


def make(capsys, *args: str) -> str:
    code = main(["dataset", "make", *args])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return captured.out


def test_a_made_dataset_reads_back_the_episodes_its_environment_plays(tmp_path, capsys):
    """Three random episodes: `load_dataset` and Minari's own reader give the same arrays,
    and each episode, replayed from its stored reset seed with its stored actions in
    seqrank's environment, gives the stored observations and rewards."""
    import minari

    out = tmp_path / "cartpole-random"
    make(capsys, "--task", CARTPOLE, "--source", "random", "--episodes", "3", "--seed", "4",
         "--out", str(out))  # fmt: skip
    dataset = load_dataset(out)
    assert dataset.task == CARTPOLE and dataset.episode_count == 3 and len(dataset) == 3000
    stored = minari.MinariDataset(out / "data")
    seeds = [m["seed"] for m in stored.storage.get_episode_metadata(range(3))]
    env = make_env(CARTPOLE)
    for e, episode in enumerate(stored.iterate_episodes()):
        first, stop = dataset.bounds(e)
        np.testing.assert_array_equal(dataset.observations[first:stop], episode.observations[:-1])
        np.testing.assert_array_equal(
            dataset.next_observations[first:stop], episode.observations[1:]
        )
        np.testing.assert_array_equal(dataset.actions[first:stop], episode.actions)
        obs, _ = env.reset(seed=int(seeds[e]))
        rewards = []
        for step, action in enumerate(episode.actions):
            np.testing.assert_allclose(obs, dataset.observations[first + step], rtol=1e-6)
            obs, reward, _, truncated, _ = env.step(action)
            rewards.append(reward)
        np.testing.assert_allclose(dataset.rewards[first:stop], rewards, rtol=1e-6)
        assert truncated and dataset.truncations[stop - 1] and not dataset.terminations.any()
    assert len(set(seeds)) == 3  # each episode its own reset seed

    code = main(["dataset", "info", str(out), "--json"])
    info = json.loads(capsys.readouterr().out)
    assert code == 0 and (info["episodes"], info["transitions"]) == (3, 3000)
    assert info["return"]["mean"] == pytest.approx(dataset.episode_returns().mean())
    assert info["success_rate"] is None  # DMControl has no success signal
    assert info["provenance"]["sources"][0]["source"] == "random"
    assert info["provenance"]["command"].startswith("seqrank dataset make --task")


def test_the_same_seed_makes_the_same_dataset_and_another_seed_another(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)  # relative paths too (Minari's storage needs them absolute)
    for name, seed in (("./a", "1"), ("b", "1"), ("c", "2")):
        make(capsys, "--task", CARTPOLE, "--source", "random", "--episodes", "1", "--seed", seed,
             "--out", name)  # fmt: skip
    a, b, c = (load_dataset(name) for name in ("a", "./b", str(tmp_path / "c")))
    np.testing.assert_array_equal(a.actions, b.actions)
    assert not np.array_equal(a.actions, c.actions)
    assert a.meta["path"] == str(tmp_path / "a")


def test_a_dataset_named_by_id_lives_in_minaris_local_folder(capsys):
    import os

    make(capsys, "--task", CARTPOLE, "--source", "random", "--episodes", "1",
         "--out", "seqrank/cartpole-test-v0")  # fmt: skip
    folder = Path(os.environ["MINARI_DATASETS_PATH"]) / "seqrank" / "cartpole-test-v0"
    assert (folder / "data" / "metadata.json").is_file()
    assert load_dataset("seqrank/cartpole-test-v0").meta["dataset_id"] == "seqrank/cartpole-test-v0"
    import minari

    assert "seqrank/cartpole-test-v0" in minari.list_local_datasets()


def test_scripted_play_with_noise_succeeds_where_random_play_does_not(tmp_path, capsys):
    """Meta-World's scripted policy with noise 0.3 against uniform random actions, six
    episodes each of button-press-topdown: at least 5 of 6 against at most 1 of 6 (seen:
    every scripted episode succeeds, no random one)."""
    out = tmp_path / "mixture"
    printed = make(capsys, "--task", "button-press-topdown", "--source", "scripted=0.5",
                   "--source", "random=0.5", "--episodes", "12", "--noise", "0.3",
                   "--out", str(out))  # fmt: skip
    assert "success" in printed
    parts = load_dataset(out).meta["sources"]
    assert [(p["source"], p["episodes"], p["first_episode"]) for p in parts] == [
        ("scripted", 6, 0),
        ("random", 6, 6),
    ]
    assert parts[0]["noise"] == 0.3
    success = episode_successes(out)
    assert success is not None
    assert success[:6].sum() >= 5 and success[6:].sum() <= 1


def test_a_runs_kept_episodes_become_a_dataset(tmp_path, capsys):
    """Medium-replay: every episode a run kept, in its order, the last observation
    repeated after the last action (a run keeps none) and each ending a truncation."""
    from seqrank.rewardbench.pool import kept_episodes
    from support.runs import run, tiny_config

    # random acting throughout (no update): the episodes are what matters here, quickly
    config = tiny_config(reward="true", steps=3000, seed_steps=3000, unsup_steps=0, eval_every=3000)
    run(tmp_path / "run", config)
    kept = kept_episodes(tmp_path / "run").episodes
    make(capsys, "--task", CARTPOLE, "--source", f"run:{tmp_path / 'run'}",
         "--out", str(tmp_path / "replay"))  # fmt: skip
    dataset = load_dataset(tmp_path / "replay")
    assert dataset.episode_count == len(kept) == 3
    for e, episode in enumerate(kept):
        first, stop = dataset.bounds(e)
        np.testing.assert_array_equal(dataset.observations[first:stop], episode.obs)
        np.testing.assert_array_equal(dataset.actions[first:stop], episode.action)
        np.testing.assert_allclose(dataset.rewards[first:stop], episode.reward, rtol=1e-6)
        np.testing.assert_array_equal(dataset.next_observations[stop - 1], episode.obs[-1])
        np.testing.assert_array_equal(dataset.next_observations[first : stop - 1], episode.obs[1:])
    assert dataset.truncations.sum() == 3 and not dataset.terminations.any()
    assert dataset.meta["sources"][0]["run"] == str(tmp_path / "run")

    make(capsys, "--task", CARTPOLE, "--source", f"run:{tmp_path / 'run'}", "--episodes", "2",
         "--out", str(tmp_path / "part"))  # fmt: skip
    part = load_dataset(tmp_path / "part")
    np.testing.assert_array_equal(part.actions[:1000], kept[0].action)  # first and last
    np.testing.assert_array_equal(part.actions[1000:], kept[2].action)


def _foreign(folder: Path, obs_dim: int, env_id: str | None = None) -> Path:
    """A dataset written by Minari's own API (no seqrank provenance)."""
    from minari.data_collector.episode_buffer import EpisodeBuffer
    from minari.dataset.minari_storage import MinariStorage

    folder.mkdir()
    spaces = {
        "observation_space": gymnasium.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32),
        "action_space": gymnasium.spaces.Box(-1.0, 1.0, (1,), np.float32),
    }
    spec = gymnasium.spec(env_id) if env_id else None
    storage = MinariStorage.new(folder / "data", env_spec=spec, **spaces)
    storage.update_metadata({"dataset_id": "foreign-v0", "minari_version": "0.5.4"})
    rng = np.random.default_rng(0)
    episode = EpisodeBuffer(
        observations=rng.normal(size=(11, obs_dim)).astype(np.float32),
        actions=rng.uniform(-1, 1, (10, 1)).astype(np.float32),
        rewards=list(rng.normal(size=10)),
        terminations=[False] * 9 + [True],
        truncations=[False] * 10,
    )
    storage.update_episodes([episode])
    return folder


def test_a_foreign_minari_dataset_loads_with_its_task_named_or_found(tmp_path, capsys):
    import seqrank  # noqa: F401  (registers the seqrank/ ids)

    unnamed = _foreign(tmp_path / "unnamed", 5)
    with pytest.raises(ValueError, match="does not name a seqrank task"):
        load_dataset(unnamed)
    dataset = load_dataset(unnamed, task="cartpole_swingup")
    assert dataset.task == CARTPOLE and len(dataset) == 10 and dataset.terminations[-1]
    assert dataset.meta["foreign"] is True
    assert main(["dataset", "info", str(unnamed), "--task", "cartpole_swingup", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["task"], info["transitions"], info["provenance"]) == (CARTPOLE, 10, None)
    with pytest.raises(ValueError, match="observations of size 5 and actions of size 1; task"):
        load_dataset(unnamed, task="walker_walk")
    pool_command = ["reward-bench", "pool", "--from-dataset", str(unnamed),
                    "--out", str(tmp_path / "pool.npz")]  # fmt: skip
    assert main(pool_command) == 2  # a pool needs the task too, in one line
    assert "does not name a seqrank task" in capsys.readouterr().err
    named = [*pool_command, "--task", "cartpole_swingup", "--random-episodes", "2"]
    assert main(named) == 0, capsys.readouterr().err
    assert main([*pool_command[:-1], str(tmp_path / "other.npz"), "--task", "walker_walk"]) == 2
    assert "observations of size 5" in capsys.readouterr().err
    found = _foreign(tmp_path / "found", 5, "seqrank/cartpole_swingup-v0")
    assert load_dataset(found).task == CARTPOLE  # from its environment spec
    with pytest.raises(ValueError, match="observations of size 4"):
        load_dataset(_foreign(tmp_path / "narrow", 4, "seqrank/cartpole_swingup-v0"))


def test_a_datasets_episodes_become_a_reward_bench_pool(tmp_path, capsys):
    from seqrank.rewardbench.pool import load_pool

    make(capsys, "--task", CARTPOLE, "--source", "random", "--episodes", "3",
         "--out", str(tmp_path / "data"))  # fmt: skip
    dataset = load_dataset(tmp_path / "data")
    code = main(["reward-bench", "pool", "--from-dataset", str(tmp_path / "data"),
                 "--out", str(tmp_path / "pool.npz")])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    pool = load_pool(tmp_path / "pool.npz")
    assert pool.task == CARTPOLE and list(pool.origin) == [0, 1, 2]  # no random play added
    np.testing.assert_array_equal(pool.obs.reshape(-1, 5), dataset.observations)
    np.testing.assert_allclose(pool.reward.reshape(-1), dataset.rewards, rtol=1e-6)
    assert pool.meta["dataset_path"] == str(tmp_path / "data")


def test_an_offline_run_as_a_source_is_named_for_what_it_is(tmp_path, capsys):
    """An offline run (IQL on a dataset) plays no episodes of its own to make a dataset of."""
    run = tmp_path / "iql-run"
    run.mkdir()
    (run / "config.json").write_text(json.dumps({"dataset": "somewhere", "task": None}))
    code = main(["dataset", "make", "--task", CARTPOLE, "--source", f"run:{run}",
                 "--out", str(tmp_path / "new")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and f"source run:{run} is an offline run" in err, err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "new").exists()


def test_ctrl_c_while_making_a_dataset_says_so_in_one_line_and_leaves_nothing(
    tmp_path, capsys, monkeypatch
):
    """A SIGINT while the episodes are written: no traceback, one line, 130 as the other
    commands exit after Ctrl-C, and neither the dataset nor the folders made for it."""
    import os
    import signal

    import seqrank.offline.minari_write as minari_write

    write = minari_write._buffers

    def interrupted(episodes):
        buffers = write(episodes)
        yield next(buffers)
        os.kill(os.getpid(), signal.SIGINT)  # a terminal's Ctrl-C, mid-way through writing
        yield from buffers

    monkeypatch.setattr(minari_write, "_buffers", interrupted)
    out = tmp_path / "new" / "cartpole"
    try:
        code = main(["dataset", "make", "--task", CARTPOLE, "--source", "random",
                     "--episodes", "2", "--out", str(out)])  # fmt: skip
    except KeyboardInterrupt:
        pytest.fail("Ctrl-C came out of `seqrank dataset make` as a traceback")
    err = capsys.readouterr().err
    assert code == 130 and err == f"interrupted: nothing written (no dataset {out})\n", err
    assert list(tmp_path.iterdir()) == []


def test_a_dataset_being_written_is_not_at_its_place_until_it_is_whole(
    tmp_path, capsys, monkeypatch
):
    """A process killed mid-write (kill -9, no handler runs) must not leave a folder that
    looks like a finished dataset: the episodes go to a staging folder renamed at the end."""
    import seqrank.offline.minari_write as minari_write

    write = minari_write._buffers
    out = tmp_path / "cartpole"
    seen_while_writing: list[bool] = []

    def watched(episodes):
        for buffer in write(episodes):
            seen_while_writing.append(out.exists())
            yield buffer

    monkeypatch.setattr(minari_write, "_buffers", watched)
    code = main(["dataset", "make", "--task", CARTPOLE, "--source", "random",
                 "--episodes", "2", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert seen_while_writing == [False, False]
    assert load_dataset(out).episode_count == 2
    assert [p.name for p in tmp_path.iterdir()] == ["cartpole"]  # no staging folder left
