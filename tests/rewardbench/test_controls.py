"""Fitting controls of the reward benchmark (issue 46, item 2): the stop rule counted over
all labels, over asked pairs only, or never (a fixed number of epochs), and closure off
(`--augments none`), as grid axes like the learner and the augmentation."""

from __future__ import annotations

import json

import pytest
from test_reward_bench import SMALL, synthetic_pool

from seqrank.cli import main
from seqrank.feedback.closure import augment
from seqrank.reward.model import RewardModel
from seqrank.rewardbench.bench import run_cell
from seqrank.rewardbench.cells import Cell
from seqrank.rewardbench.grid import read_rows, run_grid
from seqrank.rewardbench.pool import save_pool
from seqrank.rewardbench.summary import format_table, method, summarise
from seqrank.types import Answer, AnsweredQuestion, Question


@pytest.fixture(scope="module")
def pool_file(tmp_path_factory):
    return save_pool(synthetic_pool(), tmp_path_factory.mktemp("pool") / "pool.npz")


def test_closure_off_keeps_the_asked_pairs_only():
    """a > b and b > c: the closure adds a > c; without it, the two answers alone."""
    answers = [
        AnsweredQuestion(Question(0, 0, 1, True), Answer.FIRST),
        AnsweredQuestion(Question(1, 1, 2, True), Answer.FIRST),
    ]
    closed = augment(answers, [3.0, 2.0, 1.0])
    assert (len(closed.pairs), closed.stats.inferred) == (3, 1)
    alone = augment(answers, [3.0, 2.0, 1.0], closure=False)
    assert [(p.first, p.second, p.inferred) for p in alone.pairs] == [(0, 1, False), (1, 2, False)]
    assert (alone.stats.inferred, alone.stats.inferred_wrong, alone.stats.answered) == (0, 0, 2)


@pytest.mark.parametrize("scheme", ["sequential", "root"])
def test_a_cell_without_closure_learns_from_its_answers_alone(scheme):
    rows = run_cell(synthetic_pool(), Cell(scheme, "oracle", 1, augment="none"), SMALL)
    assert [(r["pairs"], r["inferred"], r["augment"]) for r in rows] == [
        (10, 0, "none"),
        (30, 0, "none"),
    ]
    assert all(r["inferred_wrong"] is None for r in rows)


def test_a_cell_that_never_stops_early_runs_every_epoch():
    rows = run_cell(synthetic_pool(), Cell("root", "oracle", 1, stop="never"), SMALL)
    assert [r["epochs"] for r in rows] == [SMALL.net.epochs] * 2
    assert all(r["stop"] == "never" for r in rows)


def test_a_cell_counts_its_stop_rule_over_the_asked_pairs(monkeypatch):
    """The fit is told which pairs were asked: as many as the answers, none inferred."""
    told = []
    train = RewardModel.train

    def spy(self, segments, first, second, labels, *args, stop_pairs=None, **kwargs):
        told.append(None if stop_pairs is None else (int(stop_pairs.sum()), len(stop_pairs)))
        return train(self, segments, first, second, labels, *args, stop_pairs=stop_pairs, **kwargs)

    monkeypatch.setattr(RewardModel, "train", spy)
    rows = run_cell(synthetic_pool(), Cell("sequential", "oracle", 1, stop="asked"), SMALL)
    assert told == [(r["answered"], r["pairs"]) for r in rows]
    assert all(r["stop"] == "asked" and r["pairs"] > r["answered"] for r in rows)
    told.clear()
    run_cell(synthetic_pool(), Cell("sequential", "oracle", 1), SMALL)
    assert told == [None, None]  # the default: every label counts, as in a run


def test_the_methods_are_named_by_their_controls():
    assert method({"learner": "plain", "augment": "none"}) == "plain+no-closure"
    assert method({"learner": "surf", "stop": "asked"}) == "surf+stop-asked"
    assert method({"augment": "checked", "stop": "never"}) == "plain+checked+stop-never"
    assert method({"augment": "full", "stop": "all"}) == method({}) == "plain"
    crowd = {"teacher": "crowd:oracle+noisy"}
    assert method({**crowd, "weighting": "none"}) == "plain"
    assert method({**crowd, "weighting": "reliability"}) == "plain+weighted"
    assert method({**crowd, "weighting": "drop"}) == "plain+dropped"
    assert method({"teacher": "oracle", "weighting": "drop"}) == "plain"


def test_the_grid_has_a_stop_axis_and_rows_before_it_stopped_over_all(pool_file, tmp_path):
    out = tmp_path / "grid"
    stops = ("all", "asked", "never")
    rows = run_grid([pool_file], ["root"], ["oracle"], [0], SMALL, out, 2, stops=stops)
    assert sorted(r["stop"] for r in rows) == sorted(2 * stops)
    old = [{k: v for k, v in r.items() if k != "stop"} for r in rows if r["stop"] == "all"]
    (out / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in old))
    seen: list[tuple[int, int]] = []
    again = run_grid(
        [pool_file], ["root"], ["oracle"], [0], SMALL, out, 1,
        lambda done, total: seen.append((done, total)),
    )  # fmt: skip
    assert again == old and seen == [(1, 1)]  # nothing run again
    table = format_table(summarise(rows))
    assert "| oracle | plain+stop-asked | 30 | root |" in table
    assert "| oracle | plain+stop-never | 30 | root |" in table


def test_the_command_takes_stop_rules_and_closure_off(pool_file, tmp_path, capsys):
    out = tmp_path / "bench"
    args = ["reward-bench", "run", "--pool", str(pool_file), "--schemes", "root", "--seeds", "1"]
    args += ["--budgets", "10", "--session-questions", "10", "--heldout-segments", "40"]
    args += ["--reward-epochs", "3", "--workers", "1", "--out", str(out)]
    assert main([*args, "--stops", "all,never", "--augments", "full,none"]) == 0
    rows = read_rows(out / "rows.jsonl")
    assert sorted((r["augment"], r["stop"]) for r in rows) == [
        ("full", "all"),
        ("full", "never"),
        ("none", "all"),
        ("none", "never"),
    ]
    effects = (out / "effects.md").read_text()
    for name in ("plain+stop-never", "plain+no-closure", "plain+no-closure+stop-never"):
        assert f"| {name} vs plain | root | 10 | 1 |" in effects
    capsys.readouterr()
