"""`seqrank reward-bench` on the input users bring: pools too small to hold an episode out,
episodes that end early (Gymnasium's MuJoCo tasks), and faults of the code, which are
tracebacks and not "bad input"."""

from __future__ import annotations

import json

import numpy as np
import pytest

from seqrank.cli import main
from seqrank.episodes import Episode
from seqrank.rewardbench.pool import load_pool, pool_from_episodes
from seqrank.training.runs import RunDir

GRID = ["--schemes", "pairwise", "--seeds", "1", "--budgets", "10", "--session-questions", "10"]
GRID += ["--heldout-segments", "10", "--reward-epochs", "2", "--workers", "1"]


def _write_pool(path, episodes: int, length: int = 60) -> None:
    """A pool file as the first format wrote it (every episode `length` steps)."""
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(episodes, length, 3)).astype(np.float32)
    meta = {"format": "seqrank-pool-1", "task": "dmc:cartpole_swingup"}
    np.savez_compressed(
        path,
        obs=obs,
        action=rng.uniform(-1, 1, (episodes, length, 1)).astype(np.float32),
        reward=obs[:, :, 0].copy(),
        origin=np.arange(episodes),
        meta=np.array(json.dumps(meta)),
    )


@pytest.mark.parametrize("episodes", [0, 1, 2])
def test_a_pool_too_small_to_hold_an_episode_out_is_refused_before_anything_is_written(
    tmp_path, capsys, episodes
):
    pool = tmp_path / "small.npz"
    _write_pool(pool, episodes)
    out = tmp_path / "grid"
    assert main(["reward-bench", "run", "--pool", str(pool), *GRID, "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1  # one line
    plural = "episode" if episodes == 1 else "episodes"
    assert f"has {episodes} {plural}; a pool needs at least 3" in error
    assert not out.exists()
    labels = tmp_path / "labels.jsonl"  # never read: the pool is refused first
    assert main(["reward-bench", "score", str(labels), "--pool", str(pool)]) == 2
    assert "a pool needs at least 3" in capsys.readouterr().err


def test_a_pool_of_three_episodes_holds_one_out_and_runs(tmp_path, capsys):
    pool = tmp_path / "three.npz"
    _write_pool(pool, 3)
    out = tmp_path / "grid"
    assert main(["reward-bench", "run", "--pool", str(pool), *GRID, "--out", str(out)]) == 0
    rows = [json.loads(line) for line in (out / "rows.jsonl").read_text().splitlines()]
    assert [row["questions"] for row in rows] == [10]


def _short_run(tmp_path, kept: int):
    """A finished true-reward run of cartpole (1000-step episodes) that kept `kept`."""
    from seqrank.config import resolve_config
    from support.runs import run

    settings = dict(reward="true", steps=1000 * kept, seed_steps=1000 * kept, device="cpu")
    settings.update(eval_every=10**6, episodes_kept=kept, hidden=32, batch=32)
    run(tmp_path / "run", resolve_config("dmc:cartpole_swingup", "small", settings))
    return tmp_path / "run"


def test_building_a_pool_too_small_is_refused_and_writes_no_file(tmp_path, capsys):
    run = _short_run(tmp_path, kept=1)
    out = tmp_path / "pool.npz"
    args = ["reward-bench", "pool", "--from-run", str(run), "--out", str(out)]
    assert main([*args, "--random-episodes", "1"]) == 2
    error = capsys.readouterr().err
    assert f"the pool of run {run} has 2 episodes; a pool needs at least 3" in error
    assert not out.exists()
    assert main([*args, "--random-episodes", "2"]) == 0
    assert len(load_pool(out)) == 3


def test_a_pool_file_already_there_is_refused_not_overwritten(tmp_path, capsys):
    """Also where --out lacks .npz: numpy adds it, and the file it names is the one checked."""
    run = _short_run(tmp_path, kept=1)
    for given, written in (("pool.npz", "pool.npz"), ("other", "other.npz")):
        args = ["reward-bench", "pool", "--from-run", str(run), "--out", str(tmp_path / given)]
        assert main([*args, "--random-episodes", "2"]) == 0
        assert f"pool {tmp_path / written}: 3 episodes" in capsys.readouterr().out
        before = (tmp_path / written).read_bytes()
        assert main([*args, "--random-episodes", "3"]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1, err
        assert (
            f"pool file {tmp_path / written} already exists; choose another --out or remove it"
            in err
        )
        assert (tmp_path / written).read_bytes() == before
    assert not (tmp_path / "other").exists()


def test_episodes_that_end_early_make_a_pool_whose_segments_lie_within_one_episode():
    """Episode k's observation column 0 is 1000 k + its step, so a segment shows which
    episode and steps it was cut from."""
    lengths = [30, 80, 120, 60, 10]
    episodes = [
        Episode(
            np.stack([1000.0 * k + np.arange(n), np.ones(n)], 1).astype(np.float32),
            np.zeros((n, 1), np.float32),
            np.full(n, 1.0 + k),
        )
        for k, n in enumerate(lengths)
    ]
    pool = pool_from_episodes("gym:Hopper-v5", episodes, 0, [], {})
    assert pool.length.tolist() == lengths and pool.obs.shape == (5, 120, 2)
    np.testing.assert_allclose(pool.returns, [n * (1.0 + k) for k, n in enumerate(lengths)])
    # B-Pref's margin: the mean return per step of the mean episode, times the segment
    returns = [n * (1.0 + k) for k, n in enumerate(lengths)]
    assert pool.margin(np.arange(5), 50) == pytest.approx(np.mean(returns) * 50 / 60)
    segments = pool.store(np.arange(5)).sample_segments(200, 50, np.random.default_rng(0))
    for steps, rewards in zip(segments.features[:, :, 0], segments.rewards, strict=True):
        episode, start = divmod(int(steps[0]), 1000)
        n = lengths[episode]
        expected = np.minimum(np.arange(start, start + 50), n - 1) + 1000 * episode
        np.testing.assert_array_equal(steps, expected)  # one episode, its last step repeated
        inside = min(50, n - start)
        assert rewards.tolist() == [1.0 + episode] * inside + [0.0] * (50 - inside)


def test_a_pool_of_a_gymnasium_task_whose_episodes_end_early_is_built_and_benchmarked(
    tmp_path, capsys
):
    """A random Hopper falls within a few dozen steps: every episode a different length."""
    pool = tmp_path / "hopper.npz"
    args = ["reward-bench", "pool", "--task", "gym:Hopper-v5", "--steps", "300"]
    assert main([*args, "--random-episodes", "2", "--out", str(pool)]) == 0
    state = RunDir.open(tmp_path / "hopper.run").load_checkpoint()
    assert state is not None
    kept = state["episodes"]["episodes"]
    loaded = load_pool(pool)
    assert len(loaded) == len(kept) + 2 and len(set(loaded.length.tolist())) > 1
    for k, episode in enumerate(kept):
        assert loaded.length[k] == len(episode.reward)
        np.testing.assert_allclose(loaded.obs[k, : len(episode.reward)], episode.obs, rtol=1e-6)
        assert not loaded.reward[k, len(episode.reward) :].any()
    out = tmp_path / "grid"
    assert main(["reward-bench", "run", "--pool", str(pool), *GRID, "--out", str(out)]) == 0
    assert "| gym:Hopper-v5 | oracle | plain | 10 | pairwise | 1 |" in capsys.readouterr().out


def _fault(*args, **kwargs):
    raise ValueError("a fault of the code")


@pytest.mark.parametrize("action", ["run", "score", "pool"])
def test_a_fault_of_the_code_is_a_traceback_not_bad_input(tmp_path, monkeypatch, action):
    """Cells run in forked processes, which see the patched function."""
    import seqrank.rewardbench.bench as bench
    import seqrank.rewardbench.grid as grid
    import seqrank.rewardbench.pool as pools

    pool = tmp_path / "pool.npz"
    _write_pool(pool, 4)
    monkeypatch.setattr(grid, "run_cell", _fault)
    monkeypatch.setattr(bench, "run_cell", _fault)
    monkeypatch.setattr(pools, "random_episodes", _fault)
    commands = {
        "run": ["run", "--pool", str(pool), *GRID, "--out", str(tmp_path / "grid")],
        "score": ["score", str(_labels(tmp_path)), "--pool", str(pool)],
        "pool": ["pool", "--from-run", str(_short_run(tmp_path, 1)), "--out", str(tmp_path / "p")],
    }
    with pytest.raises(ValueError, match="a fault of the code"):
        main(["reward-bench", *commands[action]])


def _labels(tmp_path):
    """A label file of one answer on cartpole (obs 3, act 1 as `_write_pool`'s)."""
    header = {"type": "header", "format": "seqrank-labels", "version": 1}
    header.update(task="dmc:cartpole_swingup", obs_dim=3, act_dim=1, segment_length=2)
    lines = [header]
    for k in range(2):
        lines.append(
            {
                "type": "segment",
                "id": f"r/0/{k}",
                "run": "r",
                "session": 0,
                "features": [[0.0] * 4] * 2,
                "rewards": [float(k)] * 2,
                "states": None,
                "context": None,
            }
        )
    lines.append(
        {
            "type": "answer",
            "run": "r",
            "scheme": "pairwise",
            "session": 0,
            "index": 0,
            "first": "r/0/0",
            "second": "r/0/1",
            "answer": "second",
        }
    )
    path = tmp_path / "labels.jsonl"
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def test_a_grid_takes_a_segment_length_up_to_the_pools_longest_episode(tmp_path, capsys):
    """`--segment-length` (LiRE's offline setting asks 25): recorded with the grid, and one
    longer than every episode of the pool refused in one line, nothing written."""
    pool = tmp_path / "three.npz"
    _write_pool(pool, 3, length=30)
    out = tmp_path / "grid"
    argv = ["reward-bench", "run", "--pool", str(pool), *GRID, "--out", str(out)]
    assert main([*argv, "--segment-length", "31"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and not out.exists()
    assert "--segment-length 31 is longer than every episode of pool" in error
    assert "accepted: 1 to 30" in error
    assert main([*argv, "--segment-length", "25"]) == 0
    assert json.loads((out / "settings.json").read_text())["segment_length"] == 25
    assert main([*argv, "--segment-length", "20"]) == 2  # another grid's folder
    assert "segment_length differ" in capsys.readouterr().err
