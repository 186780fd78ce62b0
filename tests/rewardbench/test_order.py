"""Segment order (issue 46, item 2): a session's new segments drawn uniformly from the
training episodes (as a run does), or the same segments given in the order the episodes
were collected; the inferred pairs of each session in the rows, for `seqrank theory`."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_reward_bench import SMALL

from seqrank.cli import main
from seqrank.episodes import Episode
from seqrank.feedback.sources import make_source
from seqrank.rewardbench.bench import run_cell
from seqrank.rewardbench.cells import Cell
from seqrank.rewardbench.grid import read_rows, run_grid
from seqrank.rewardbench.order import CollectionOrder
from seqrank.rewardbench.pool import pool_from_episodes, save_pool
from seqrank.rewardbench.summary import format_table, method, summarise


def labelled_pool(trained: int = 12, random: int = 3, length: int = 60):
    """Feature 0 is the reward (rising with the episode, as skill does); feature 1 names
    the step: the episode's place in the pool + the step / 1000."""
    rng = np.random.default_rng(0)
    episodes = []
    for e in range(trained + random):
        obs = rng.normal(size=(length, 3)).astype(np.float32)
        obs[:, 0] += (e - trained / 2) / trained if e < trained else -1.0
        obs[:, 1] = e + np.arange(length) / 1000
        action = rng.uniform(-1, 1, size=(length, 1)).astype(np.float32)
        episodes.append(Episode(obs, action, obs[:, 0].copy()))
    return pool_from_episodes(
        "dmc:cartpole_swingup", episodes[:trained], 40, episodes[trained:], {}
    )


def collection_keys(pool, features):
    """(origin, place, step) of each segment: when it was collected (random play, -1,
    first; its episodes in their place in the pool)."""
    code = np.round(features[:, 0, 1].astype(np.float64) * 1000).astype(int)
    return [(int(pool.origin[c // 1000]), int(c // 1000), int(c % 1000)) for c in code]


def test_the_collection_order_gives_the_uniform_segments_in_the_order_collected():
    pool = labelled_pool()
    train, _ = pool.split()
    uniform = pool.store(train).sample_segments(30, 20, np.random.default_rng(5))
    store, rng = CollectionOrder(pool, train), np.random.default_rng(5)
    ordered = store.sample_segments(30, 20, rng, in_order=True)
    keys = collection_keys(pool, ordered.features)
    assert keys == sorted(keys) and keys[0][0] == -1  # random play first, then by origin
    assert sorted(map(tuple, ordered.features[:, 0, :2])) == sorted(
        map(tuple, uniform.features[:, 0, :2])
    )  # the same segments: the same draws of the same stream
    rows = {tuple(f[0, :2]): r for f, r in zip(uniform.features, uniform.rewards, strict=True)}
    for feature, reward in zip(ordered.features, ordered.rewards, strict=True):
        np.testing.assert_array_equal(rows[tuple(feature[0, :2])], reward)


class _Recording:
    """The oracle, keeping each session's segments in the order its questions showed them."""

    def __init__(self) -> None:
        self.teacher = make_source("oracle")
        self.shown: list[np.ndarray] = []

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request):
        segments, record = self.teacher.ask_session(request)
        order = dict.fromkeys(s for a in record.answers for s in (a.first, a.second))
        self.shown.append(segments.features[list(order)])
        return segments, record


@pytest.mark.parametrize("scheme", ["pairwise", "sequential", "root"])
def test_a_collection_cell_shows_each_sessions_segments_in_rising_order(scheme):
    pool = labelled_pool()
    ordered, uniform = _Recording(), _Recording()
    run_cell(pool, Cell(scheme, "oracle", 1, order="collection"), SMALL, ordered)
    run_cell(pool, Cell(scheme, "oracle", 1), SMALL, uniform)
    for shown in ordered.shown:
        keys = collection_keys(pool, shown)
        assert keys == sorted(keys)
    first = collection_keys(pool, uniform.shown[0])
    assert first != sorted(first)  # uniform: in the order drawn
    assert sorted(first) == collection_keys(pool, ordered.shown[0])  # the same segments


def test_the_rows_give_each_sessions_inferred_pairs_and_clips():
    rows = run_cell(labelled_pool(), Cell("root", "oracle", 2, order="collection"), SMALL)
    assert [len(r["session_inferred"]) for r in rows] == [1, 3]  # sessions of 10 questions
    assert [sum(r["session_inferred"]) for r in rows] == [r["inferred"] for r in rows]
    assert rows[-1]["session_clips"] == [11, 11, 11]  # M = 11 segments, 10 questions each
    assert rows[-1]["session_inferred"][:1] == rows[0]["session_inferred"]
    assert all(r["order"] == "collection" for r in rows)
    pairwise = run_cell(labelled_pool(), Cell("pairwise", "oracle", 2), SMALL)
    assert pairwise[-1]["session_inferred"] == [0, 0, 0]
    assert pairwise[-1]["session_clips"] == [20, 20, 20]


def test_the_grid_has_an_order_axis_and_rows_before_it_are_uniform(tmp_path):
    pool_file = save_pool(labelled_pool(), tmp_path / "pool.npz")
    out = tmp_path / "grid"
    orders = ("uniform", "collection")
    rows = run_grid([pool_file], ["root"], ["oracle"], [0], SMALL, out, 2, orders=orders)
    assert sorted(r["order"] for r in rows) == sorted(2 * orders)
    old = [{k: v for k, v in r.items() if k != "order"} for r in rows if r["order"] == "uniform"]
    (out / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in old))
    seen: list[tuple[int, int]] = []
    again = run_grid(
        [pool_file], ["root"], ["oracle"], [0], SMALL, out, 1,
        lambda done, total: seen.append((done, total)),
    )  # fmt: skip
    assert again == old and seen == [(1, 1)]  # nothing run again
    assert "| oracle | plain+collection | 30 | root |" in format_table(summarise(rows))
    assert method({"order": "collection", "stop": "asked"}) == "plain+stop-asked+collection"


def test_the_command_takes_orders(tmp_path, capsys):
    pool_file = save_pool(labelled_pool(), tmp_path / "pool.npz")
    out = tmp_path / "bench"
    args = ["reward-bench", "run", "--pool", str(pool_file), "--schemes", "root", "--seeds", "1"]
    args += ["--budgets", "10", "--session-questions", "10", "--heldout-segments", "40"]
    args += ["--reward-epochs", "3", "--workers", "1", "--out", str(out)]
    assert main([*args, "--orders", "uniform,collection"]) == 0
    assert sorted(r["order"] for r in read_rows(out / "rows.jsonl")) == ["collection", "uniform"]
    assert "| plain+collection vs plain | root | 10 | 1 |" in (out / "effects.md").read_text()
    capsys.readouterr()
