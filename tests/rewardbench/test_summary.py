"""The reward benchmark's summary and effects: means and 95% intervals (within each
measure's range) per scheme and budget, each method against plain seed by seed, and
`reward-bench report`."""

from __future__ import annotations

import json
import math
import re

import pytest

from seqrank.cli import main
from seqrank.rewardbench.intervals import bounded_interval
from seqrank.rewardbench.summary import (
    format_effects,
    paired_effects,
    summarise,
)

T_97_5 = {1: 12.706204736, 2: 4.302652730}  # Student's t, 97.5%, by degrees of freedom


def _logit_interval(values, low, high):
    """By hand: a t-interval on the logit of each value's place in [low, high], mapped back."""
    logits = [math.log((v - low) / (high - v)) for v in values]
    n, mean = len(values), sum(logits) / len(values)
    sd = math.sqrt(sum((z - mean) ** 2 for z in logits) / (n - 1))
    half = T_97_5[n - 1] * sd / math.sqrt(n)
    back = [low + (high - low) / (1 + math.exp(-z)) for z in (mean - half, mean + half)]
    return sum(values) / n, back[0], back[1]


def test_the_interval_is_a_t_interval_on_the_logit_scale_within_the_range():
    assert bounded_interval([0.6, 0.7, 0.8], 0, 1) == pytest.approx(
        _logit_interval([0.6, 0.7, 0.8], 0, 1)
    )
    # a correlation: the logit of (1 + r) / 2 is twice Fisher's z
    assert bounded_interval([0.2, 0.9], -1, 1) == pytest.approx(_logit_interval([0.2, 0.9], -1, 1))
    assert bounded_interval([0.7], 0, 1) == (0.7, None, None)  # one seed: no interval
    assert bounded_interval([1.0, 1.0], 0, 1) == (1.0, 1.0, 1.0)  # the seeds agree
    mean, low, high = bounded_interval([0.9, 1.0], 0, 1)  # 1 is taken as 0.999
    assert 0 <= low < mean < high <= 1


def test_the_summary_has_a_mean_and_interval_per_scheme_and_budget():
    rows = [
        {
            "task": "t",
            "teacher": "oracle",
            "scheme": s,
            "questions": q,
            "pairs": q,
            "seed": k,
            "accuracy": 0.5 + k / 10,
            "spearman": 0.1,
            "inferred_wrong": None,
        }
        for s in ("root", "pairwise")
        for q in (10, 20)
        for k in range(3)
    ]
    summary = summarise(rows)
    assert [(e["scheme"], e["questions"]) for e in summary] == [
        ("pairwise", 10),
        ("pairwise", 20),
        ("root", 10),
        ("root", 20),
    ]
    assert summary[0]["accuracy"][0] == pytest.approx(0.6) and summary[0]["inferred_wrong"] is None


def effect_rows(differences, learner="rime", seeds_of_baseline=4):
    """Rows of plain and one learner on one task, teacher and scheme at 10 questions: the
    learner's accuracy is plain's plus the given difference, seed by seed."""
    rows = []
    for seed in range(seeds_of_baseline):
        plain = 0.6 + seed / 10  # seeds differ far more than the methods do
        common = {"task": "t", "teacher": "mistake", "scheme": "root", "questions": 10}
        common |= {"seed": seed, "pairs": 10, "spearman": plain}
        rows.append({**common, "learner": "plain", "accuracy": plain, "inferred_wrong": 0.3})
        if seed < len(differences):
            learned = plain + differences[seed]
            row = {**common, "learner": learner, "accuracy": learned, "spearman": learned}
            rows.append({**row, "inferred_wrong": 0.1})
    return rows


def test_each_method_is_compared_with_plain_seed_by_seed():
    [effect] = paired_effects(effect_rows([0.02, 0.03, 0.04]))
    # three pairs (the baseline's fourth seed has no partner); the seeds' spread cancels
    assert (effect["method"], effect["baseline"], effect["seeds"]) == ("rime", "plain", 3)
    assert effect["accuracy_difference"] == pytest.approx(
        _logit_interval([0.02, 0.03, 0.04], -1, 1)
    )
    assert effect["spearman_difference"][0] == pytest.approx(0.03)
    assert (effect["inferred_wrong"], effect["baseline_inferred_wrong"]) == pytest.approx(
        (0.1, 0.3)
    )
    assert effect["verdict"] == "helps"
    assert paired_effects(effect_rows([-0.02, -0.03, -0.04]))[0]["verdict"] == "hurts"
    assert paired_effects(effect_rows([-0.02, 0.0, 0.02]))[0]["verdict"] == "no clear difference"
    assert paired_effects(effect_rows([0.5]))[0]["verdict"] == "one seed"
    # the same model on every seed (checked on pairwise, which infers nothing): said plainly
    assert paired_effects(effect_rows([0.0, 0.0]))[0]["verdict"] == "identical"
    # the matrix at the top of effects.md: a table per teacher and budget, scheme by method
    matrix = format_effects(paired_effects(effect_rows([0.02, 0.03, 0.04])))
    assert "## t, mistake, 10 questions\n\n| scheme | rime |" in matrix
    assert "| root | +0.030 [+0.005, +0.055] **helps** |" in matrix
    # checked augmentation is its own method; rows of the baseline alone compare nothing
    checked = [{**r, "augment": "checked"} for r in effect_rows([0.0, 0.1], learner="plain")]
    names = {e["method"] for e in paired_effects(effect_rows([0.1, 0.2]) + checked[1::2])}
    assert names == {"rime", "plain+checked"}
    assert paired_effects(effect_rows([])) == []
    table = format_effects(paired_effects(effect_rows([0.02, 0.03, 0.04])))
    assert "| t | mistake | rime vs plain | root | 10 | 3 | +0.030 [" in table
    assert (
        "| 0.100 (0.300) | helps |" in table and "1 in 20 reads helps or hurts by chance" in table
    )
    assert "| +0.500 | +0.500 |" in format_effects(paired_effects(effect_rows([0.5])))


def test_a_method_is_paired_with_plain_of_its_own_teacher_scheme_and_budget():
    """Plain's accuracy differs by teacher, scheme and budget far more than the method's gain
    does: pairing across them would give other differences."""
    gains = {("oracle", "root", 10): 0.01, ("oracle", "root", 20): 0.02}
    gains |= {("oracle", "pairwise", 10): -0.03, ("mistake", "root", 10): 0.04}
    rows = []
    for k, ((teacher, scheme, questions), gain) in enumerate(gains.items()):
        for seed in range(3):
            common = {"task": "t", "teacher": teacher, "scheme": scheme, "questions": questions}
            common |= {"seed": seed, "pairs": questions, "spearman": 0.5, "inferred_wrong": None}
            plain = 0.3 + k / 10 + seed / 100
            rows.append({**common, "learner": "plain", "accuracy": plain})
            rows.append({**common, "learner": "surf", "accuracy": plain + gain})
    found = {
        (e["teacher"], e["scheme"], e["questions"]): e["accuracy_difference"][0]
        for e in paired_effects(rows)
    }
    assert found == pytest.approx(gains)
    # schemes in the package's order, then budgets
    assert [e["scheme"] for e in paired_effects(rows) if e["teacher"] == "oracle"] == [
        "pairwise",
        "root",
        "root",
    ]
    with pytest.raises(ValueError, match="two rows of surf for task t, teacher oracle, scheme"):
        paired_effects([*rows, rows[1]])


def test_the_report_action_rewrites_a_folders_table_and_effects(tmp_path, capsys):
    folder = tmp_path / "grid"
    folder.mkdir()
    rows = effect_rows([0.02, 0.03, 0.04])
    (folder / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert main(["reward-bench", "report", str(folder)]) == 0
    assert "| t | mistake | rime | 10 | root | 3 |" in capsys.readouterr().out
    assert "rime vs plain" in (folder / "effects.md").read_text()
    assert json.loads((folder / "effects.json").read_text())[0]["verdict"] == "helps"
    assert (folder / "curves_t.png").read_bytes()[:4] == b"\x89PNG"
    assert main(["reward-bench", "report", str(folder), "--baseline", "surf"]) == 2
    assert "--baseline 'surf' has no rows in" in capsys.readouterr().err
    assert main(["reward-bench", "report", str(folder), "--baseline", "rime"]) == 0
    assert "plain vs rime" in (folder / "effects.md").read_text()
    # a folder merged by hand with one cell twice: named, not paired at random
    (folder / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in [*rows, rows[0]]))
    assert main(["reward-bench", "report", str(folder)]) == 2
    assert "two rows of plain for task t, teacher mistake" in capsys.readouterr().err


def test_intervals_of_two_seeds_stay_in_range_and_one_seed_prints_none(tmp_path, capsys):
    """Two seeds (t with 1 degree of freedom: 12.7 standard errors) near the top of the
    range, and a budget with one seed; rime beside plain for effects.md."""
    common = {"task": "t", "teacher": "oracle", "scheme": "root", "inferred_wrong": None}
    rows = []
    for seed, (plain, rime) in enumerate([(0.3, 0.8), (0.05, 0.95)]):
        for learner, accuracy in (("plain", plain), ("rime", rime)):
            row = {**common, "seed": seed, "questions": 10, "pairs": 10, "learner": learner}
            rows.append({**row, "accuracy": accuracy, "spearman": accuracy})
    rows.append({**rows[0], "questions": 20, "seed": 0})  # one seed of plain at 20
    folder = tmp_path / "grid"
    folder.mkdir()
    (folder / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert main(["reward-bench", "report", str(folder)]) == 0
    table = (folder / "table.md").read_text()
    interval = re.compile(r"([-\d.]+) \[([-\d.]+), ([-\d.]+)\]")
    for line in table.splitlines()[2:]:
        columns = line.split("|")
        for column, bottom in ((8, 0.0), (9, -1.0)):  # accuracy in [0, 1], Spearman [-1, 1]
            for mean, low, high in interval.findall(columns[column]):
                assert bottom <= float(low) <= float(mean) <= float(high) <= 1, line
    assert "| t | oracle | plain | 20 | root | 1 | 10 | 0.300 (n=1) | 0.300 (n=1) |" in table
    low, high = _logit_interval([0.3, 0.05], -1, 1)[1:]
    assert f"| 0.175 [{low:.3f}, {high:.3f}] |" in table  # plain's Spearman at 10
    effects = (folder / "effects.md").read_text()
    [matrix] = re.findall(r"\| root \| \+0\.700 \[([-+\d.]+), ([-+\d.]+)\]", effects)
    assert -1 <= float(matrix[0]) < 0.7 < float(matrix[1]) <= 1  # differences lie in [-1, 1]
