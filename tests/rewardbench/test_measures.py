"""The reward benchmark's measures at the top of the held-out segments (issue 46, item 2):
preference accuracy among the top quarter, recall of the true top 10% and the regret of
picking the best of 10 by the learned reward, each worked out by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest

from seqrank.cli import main
from seqrank.rewardbench.measures import pick_regret, top_accuracy, top_recall
from seqrank.rewardbench.summary import format_effects, format_table, paired_effects, summarise

TOP = ("top_accuracy", "top_recall", "regret")


def test_a_perfect_model_scores_one_one_and_no_regret():
    truth = np.arange(40.0)
    predicted = 3.0 * truth - 7.0  # any rising function of the truth
    assert top_accuracy(predicted, truth) == 1.0
    assert top_recall(predicted, truth) == 1.0
    assert pick_regret(predicted, truth) == 0.0


def test_a_reversed_model_scores_nothing_and_the_most_regret():
    truth = np.arange(10.0)
    assert top_accuracy(-truth, truth) == 0.0
    assert top_recall(-truth, truth) == 0.0
    # 10 segments, 10 to pick from: every draw is all of them, and the reversed model
    # picks the worst: the true range, the whole of it
    assert pick_regret(-truth, truth) == 1.0


def test_the_regret_of_a_reversed_model_is_the_mean_spread_of_ten_of_fifty():
    """Ten of 0..49 at random: E[max] - E[min] = (k - 1)(n + 1) / (k + 1) = 9 x 51 / 11;
    divided by the range, 49: 0.8516. 1000 draws: a standard error near 0.002."""
    truth = np.arange(50.0)
    assert pick_regret(-truth, truth) == pytest.approx(9 * 51 / 11 / 49, abs=0.01)
    assert pick_regret(-truth, truth) == pick_regret(-truth, truth)  # a fixed generator


def test_a_small_example_by_hand():
    """Truths 0..11; the model puts segment 9 on top (11.5), the others where they are.
    Top quarter: 9, 10, 11; of its three pairs only (10, 11) is ordered right: 1/3. True
    top 10% (2 of 12): 10, 11; predicted: 9, 11: half found. Best of all 12: the model
    picks 9 (truth 9) where 11 was there: a regret of 2, over the range 11."""
    truth = np.arange(12.0)
    predicted = truth.copy()
    predicted[9] = 11.5
    assert top_accuracy(predicted, truth) == pytest.approx(1 / 3)
    assert top_recall(predicted, truth) == 0.5
    assert pick_regret(predicted, truth, k=12) == pytest.approx(2 / 11)
    # two of three at random (k=2 of 0, 1, 2), the model reversed: the pairs {0, 1},
    # {0, 2}, {1, 2} give regrets 1, 2, 1: 4/3 on average, 2/3 of the range
    assert pick_regret(-truth[:3], truth[:3], k=2) == pytest.approx(2 / 3, abs=0.03)
    # a top quarter of equal truths orders nothing: no value rather than a made-up one
    assert top_accuracy(np.arange(8.0), np.ones(8)) is None
    assert pick_regret(np.arange(8.0), np.ones(8)) == 0.0


def _rows(measures_of_seed):
    rows = []
    for seed, (top, recall, regret) in enumerate(measures_of_seed):
        common = {"task": "t", "teacher": "oracle", "scheme": "root", "questions": 10}
        common |= {"seed": seed, "pairs": 10, "inferred_wrong": None}
        base = {"accuracy": 0.7, "spearman": 0.5, "top_accuracy": 0.6, "top_recall": 0.4}
        rows.append({**common, **base, "regret": 0.2, "learner": "plain"})
        mine = {"top_accuracy": top, "top_recall": recall, "regret": regret}
        rows.append({**common, **base, **mine, "learner": "surf"})
    return rows


def test_the_summary_table_and_effects_carry_the_top_measures(tmp_path, capsys):
    rows = _rows([(0.7, 0.5, 0.1), (0.8, 0.6, 0.15), (0.75, 0.55, 0.05)])
    summary = summarise(rows)
    surf = next(e for e in summary if e["learner"] == "surf")
    assert surf["top_accuracy"][0] == pytest.approx(0.75)
    assert surf["top_recall"][0] == pytest.approx(0.55)
    assert surf["regret"][0] == pytest.approx(0.1)
    assert all(0 <= surf[m][1] <= surf[m][0] <= surf[m][2] <= 1 for m in TOP)
    table = format_table(summary)
    assert "top-quarter accuracy" in table and "top-10% recall" in table
    assert "regret (best of 10)" in table
    assert "| 0.750 [" in table
    [effect] = paired_effects(rows)
    assert effect["top_accuracy_difference"][0] == pytest.approx(0.15)
    assert effect["top_recall_difference"][0] == pytest.approx(0.15)
    assert effect["regret_difference"][0] == pytest.approx(-0.1)
    assert "regret difference" in format_effects([effect])
    # rows written before these measures: their columns read '-', nothing fails
    old = [{k: v for k, v in r.items() if k not in TOP} for r in rows]
    [entry] = [e for e in summarise(old) if e["learner"] == "surf"]
    assert all(entry[m] is None for m in TOP)
    assert paired_effects(old)[0]["regret_difference"] is None
    folder = tmp_path / "grid"
    folder.mkdir()
    (folder / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in old))
    assert main(["reward-bench", "report", str(folder)]) == 0
    assert "| t | oracle | surf | 10 | root | 3 |" in capsys.readouterr().out
