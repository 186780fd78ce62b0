"""Pools that follow a learning policy (issue 46, item 2): `--window-steps N`, one session
per window of the pool's run, each budget scored on the next window."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from test_reward_bench import SMALL

import seqrank.rewardbench.bench as bench
from seqrank.cli import main
from seqrank.episodes import Episode
from seqrank.feedback.sources import make_source
from seqrank.rewardbench.bench import run_cell
from seqrank.rewardbench.cells import Cell
from seqrank.rewardbench.grid import read_rows, run_grid
from seqrank.rewardbench.pool import pool_from_episodes, save_pool
from seqrank.rewardbench.windows import episode_windows

# the run's episode lengths; their ends (steps 30, 100, 150, 210, 250, 300, 350, 450, 480,
# 500) in windows of 100 steps: an episode is in the window of its last step (100: 0)
LENGTHS = [30, 70, 50, 60, 40, 50, 50, 100, 30, 20]
WINDOWS = [[0, 1], [2], [3, 4, 5], [6], [7, 8, 9]]
RANDOM = [10, 11]  # the pool's random-play episodes: in no window
WINDOWED = replace(SMALL, window_steps=100)  # budgets 10, 30 of 10 a session: 3 sessions
PRE_WINDOW_KEYS = [
    "task", "scheme", "teacher", "learner", "augment", "weighting", "stop", "order", "seed",
    "questions", "answered", "pairs", "inferred", "inferred_wrong", "asked_wrong",
    "accuracy", "spearman", "top_accuracy", "top_recall", "regret", "epochs", "clips",
    "annotator_seconds", "session_inferred", "session_clips", "seconds",
]  # fmt: skip


def windowed_pool(lengths=LENGTHS, first_index: int = 0):
    """Feature 0 is the reward (rising with the episode, as skill does); feature 1 names
    the segment's episode: its place in the pool + the step / 1000."""
    rng = np.random.default_rng(0)
    episodes = []
    for e, n in enumerate([*lengths, 40, 40]):
        obs = rng.normal(size=(n, 3)).astype(np.float32)
        obs[:, 0] += e / len(lengths) if e < len(lengths) else -1.0
        obs[:, 1] = e + np.arange(n) / 1000
        action = rng.uniform(-1, 1, size=(n, 1)).astype(np.float32)
        episodes.append(Episode(obs, action, obs[:, 0].copy()))
    run, extra = episodes[: len(lengths)], episodes[len(lengths) :]
    return pool_from_episodes("dmc:cartpole_swingup", run, first_index, extra, {})


def episodes_of(features: np.ndarray) -> set[int]:
    return set(np.floor(features[:, :, 1].astype(np.float64)).astype(int).ravel().tolist())


def margin_by_hand(pool, which: list[int]) -> float:
    """B-Pref's margin: the episodes' mean return, per step of their mean length, x 20."""
    returns = [pool.reward[e, : pool.length[e]].sum() for e in which]
    return float(np.mean(returns)) * 20 / float(np.mean(pool.length[which]))


class _Recording:
    """The oracle, keeping each session's segments and margin."""

    def __init__(self) -> None:
        self.teacher = make_source("oracle")
        self.segments: list[np.ndarray] = []
        self.margins: list[float] = []

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request):
        self.segments.append(request.segments.features)
        self.margins.append(request.margin)
        return self.teacher.ask_session(request)


@pytest.fixture
def scored(monkeypatch):
    """The held-out segments each row was measured on, and the episodes each fit's
    unlabelled pairs (SURF's) could be cut from."""
    seen: dict[str, list] = {"heldout": [], "unlabelled": []}

    def measures(model, segments):
        seen["heldout"].append(segments.features)
        return real_measures(model, segments)

    def unlabelled(learner, episodes, *args):
        seen["unlabelled"].append(
            episodes_of(np.concatenate([e.obs for e in episodes.episodes])[None])
        )
        return real_unlabelled(learner, episodes, *args)

    real_measures, real_unlabelled = bench.heldout_measures, bench.give_unlabelled
    monkeypatch.setattr(bench, "heldout_measures", measures)
    monkeypatch.setattr(bench, "give_unlabelled", unlabelled)
    return seen


def test_the_windows_are_the_run_episodes_by_the_step_they_ended():
    pool = windowed_pool()
    assert [w.tolist() for w in episode_windows(pool, 100)] == WINDOWS
    # complete windows only: the run's 500 steps hold two of 200, the second to step 399
    assert [w.tolist() for w in episode_windows(pool, 200)] == [[0, 1, 2], [3, 4, 5, 6]]


@pytest.mark.parametrize("order", ["uniform", "collection"])
def test_session_k_asks_about_window_k_and_its_row_is_scored_on_the_next(scored, order):
    pool, source = windowed_pool(), _Recording()
    cell = Cell("root", "oracle", 1, "surf", order=order)
    rows = run_cell(pool, cell, WINDOWED, source)
    assert len(source.segments) == 3
    for k, features in enumerate(source.segments):
        assert episodes_of(features) <= set(WINDOWS[k])  # never another's, nor random play
        assert source.margins[k] == pytest.approx(margin_by_hand(pool, WINDOWS[k]), rel=1e-5)
        if order == "collection":  # the window's segments in the order they were collected
            code = features[:, 0, 1].astype(np.float64)
            assert code.tolist() == sorted(code.tolist())
    # a row after session k (budget 10: 0; budget 30: 2) is measured on window k + 1 ...
    assert [(r["window"], r["scored_window"]) for r in rows] == [(0, 1), (2, 3)]
    assert [episodes_of(f) for f in scored["heldout"]] == [set(WINDOWS[1]), set(WINDOWS[3])]
    # ... and its unlabelled pairs come from the windows seen so far
    assert scored["unlabelled"] == [set(WINDOWS[0]), {e for w in WINDOWS[:3] for e in w}]


def test_sessions_cut_short_at_a_budget_take_a_window_each(scored):
    """Budgets 15 and 30 of 10 a session: sessions of 10, 5, 10, 5 questions."""
    settings = replace(WINDOWED, budgets=(15, 30))
    source = _Recording()
    rows = run_cell(windowed_pool(), Cell("pairwise", "oracle", 0), settings, source)
    assert [episodes_of(f) <= set(WINDOWS[k]) for k, f in enumerate(source.segments)] == [True] * 4
    assert [(r["questions"], r["window"], r["scored_window"]) for r in rows] == [
        (15, 1, 2),
        (30, 3, 4),
    ]
    assert [episodes_of(f) for f in scored["heldout"]] == [set(WINDOWS[2]), set(WINDOWS[4])]


def test_without_windows_sessions_use_the_split_and_rows_keep_their_keys(scored):
    pool, source = windowed_pool(), _Recording()
    train, held = pool.split()
    rows = run_cell(pool, Cell("root", "oracle", 1, "surf"), SMALL, source)
    assert all(episodes_of(f) <= set(train.tolist()) for f in source.segments)
    assert set(RANDOM) & set(train.tolist())  # random play is asked about: no windows here
    assert source.margins == [pytest.approx(margin_by_hand(pool, train.tolist()), rel=1e-5)] * 3
    fixed = pool.heldout_segments(held, SMALL.heldout_segments, SMALL.segment_length)
    assert all(np.array_equal(f, fixed.features) for f in scored["heldout"])
    assert scored["unlabelled"] == [set(train.tolist())] * 2
    learner_keys = [k for k in rows[0] if k.startswith("surf_")]  # the fit's, as before
    assert [list(r) for r in rows] == [
        PRE_WINDOW_KEYS[:21] + learner_keys + PRE_WINDOW_KEYS[21:]
    ] * 2


def _grid_args(pool_file, out, *more):
    args = ["reward-bench", "run", "--pool", str(pool_file), "--schemes", "root", "--seeds", "1"]
    args += ["--budgets", "10,30", "--session-questions", "10", "--heldout-segments", "40"]
    return [*args, "--reward-epochs", "3", "--workers", "1", "--out", str(out), *more]


def test_the_command_runs_windows_and_keeps_their_setting(tmp_path, capsys):
    pool_file = save_pool(windowed_pool(), tmp_path / "pool.npz")
    out = tmp_path / "bench"
    assert main(_grid_args(pool_file, out, "--window-steps", "100")) == 0
    rows = read_rows(out / "rows.jsonl")
    assert [(r["window"], r["scored_window"]) for r in rows] == [(0, 1), (2, 3)]
    assert json.loads((out / "settings.json").read_text())["window_steps"] == 100
    capsys.readouterr()
    for other in (["--window-steps", "120"], []):  # another window, or none: refused
        assert main(_grid_args(pool_file, out, *other)) == 2
        assert "other settings (window_steps differ)" in capsys.readouterr().err
    assert read_rows(out / "rows.jsonl") == rows


def test_a_folder_made_before_windows_continues_without_them(tmp_path):
    """Its settings.json has no window_steps: it stands for none, and nothing runs again."""
    pool_file = save_pool(windowed_pool(), tmp_path / "pool.npz")
    out = tmp_path / "grid"
    rows = run_grid([pool_file], ["root"], ["oracle"], [0], SMALL, out, 1)
    assert not any("window" in r for r in rows)
    saved = json.loads((out / "settings.json").read_text())
    del saved["window_steps"]
    (out / "settings.json").write_text(json.dumps(saved))
    seen: list[tuple[int, int]] = []
    again = run_grid(
        [pool_file], ["root"], ["oracle"], [0], SMALL, out, 1,
        lambda done, total: seen.append((done, total)),
    )  # fmt: skip
    assert again == rows and seen == [(1, 1)]


def _gapped_pool():
    pool = windowed_pool()
    origin = pool.origin.copy()
    origin[3:10] += 1  # the run's episode 3 is missing
    return replace(pool, origin=origin)


@pytest.mark.parametrize(
    ("pool", "more", "said"),
    [
        (
            windowed_pool(first_index=5),
            ["--window-steps", "100"],
            "holds 10 of its run's episodes 5 to 14, not all of 0 to 14 (missing: 0, 1, 2, 3, "
            "4); windows count steps from the run's start and need every episode from 0 on "
            "(made from a run that kept only its last episodes: make the pool from a run "
            "with episodes_kept at least its episode count)",
        ),
        (
            _gapped_pool(),
            ["--window-steps", "100"],
            "episodes 0 to 10, not all of 0 to 10 (missing: 3)",
        ),
        (
            windowed_pool(),
            ["--window-steps", "60"],
            "--window-steps 60: no episode of the pool's run ended within window 6 (steps 360 "
            "to 419); its episodes are up to 100 steps long: give --window-steps 100 or more",
        ),
        (
            windowed_pool(),
            ["--window-steps", "150"],
            "--window-steps 150: the pool's run (500 steps) has 3 complete windows, and "
            "budgets up to 30 at 10 questions a session need 4 (3 sessions, one window each, "
            "and the next to score on): give --window-steps 125 or less",
        ),
        (  # budgets 15 and 30 of 10 a session: sessions of 10, 5, 10, 5 questions
            windowed_pool(),
            ["--window-steps", "120", "--budgets", "15,30"],
            "has 4 complete windows, and budgets up to 30 at 10 questions a session need 5 "
            "(4 sessions",
        ),
        (windowed_pool(), ["--window-steps", "0"], "argument --window-steps: 0 is out of range"),
    ],
)
def test_a_pool_without_the_windows_asked_for_is_refused_before_anything_is_written(
    tmp_path, capsys, pool, more, said
):
    pool_file = save_pool(pool, tmp_path / "pool.npz")
    out = tmp_path / "grid"
    assert main(_grid_args(pool_file, out, *more)) == 2
    error = capsys.readouterr().err
    assert said in error and error.count("\n") == 1, error
    assert not out.exists()
