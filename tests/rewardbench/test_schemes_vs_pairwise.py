"""`scripts/schemes_vs_pairwise.py`: each scheme minus pairwise in the same order, budget
and seed; per clip a scheme's 2q questions against pairwise's q; fitting controls left
out (effects.md compares them within their scheme)."""

from __future__ import annotations

import json

import pytest

from support.scripts import load_script


@pytest.fixture(scope="module")
def script():
    return load_script("schemes_vs_pairwise")


def _row(scheme, seed, questions, accuracy, stop="all"):
    return {
        "task": "t", "scheme": scheme, "order": "uniform", "seed": seed, "stop": stop,
        "questions": questions, "accuracy": accuracy, "spearman": 0.0, "top_accuracy": 0.5,
        "top_recall": 0.5, "regret": 0.1,
    }  # fmt: skip


def test_differences_are_paired_by_seed_per_question_and_per_clip(script, tmp_path):
    rows = [
        _row("pairwise", 0, 10, 0.60), _row("pairwise", 1, 10, 0.70),
        _row("pairwise", 0, 20, 0.80), _row("pairwise", 1, 20, 0.90),
        _row("root", 0, 20, 0.70), _row("root", 1, 20, 0.90),
        _row("root", 0, 10, 0.10, stop="never"),  # a control: not a root row
    ]  # fmt: skip
    (tmp_path / "rows.jsonl").write_text("\n".join(json.dumps(r) for r in rows))
    loaded = script.read_rows(tmp_path)
    assert ("t", "uniform", "root", 10, 0) not in loaded
    # per question at 20: (0.7 - 0.8 + 0.9 - 0.9) / 2
    assert script.difference(loaded, ("t", "uniform", "root", 20), 20, "accuracy").startswith(
        "-0.050 ["
    )
    # per clip: root's 20 questions against pairwise's 10: (0.1 + 0.2) / 2
    per_clip = script.difference(loaded, ("t", "uniform", "root", 20), 10, "accuracy")
    assert per_clip.startswith("+0.150 [")
    assert script.difference(loaded, ("t", "uniform", "root", 10), 10, "accuracy") == "-"
    clip_rows = [line for line in script.per_clip(loaded) if line.startswith("| t |")]
    assert clip_rows == [f"| t | uniform | root | 20 | 10 | {per_clip} |"]


def test_another_order_is_set_against_pairwise_in_the_order_named(script, tmp_path):
    rows = [
        _row("pairwise", 0, 10, 0.60), _row("pairwise", 1, 10, 0.70),
        {**_row("pairwise", 0, 10, 0.50), "order": "collection"},
        {**_row("pairwise", 1, 10, 0.50), "order": "collection"},
        {**_row("root", 0, 10, 0.80), "order": "collection"},
        {**_row("root", 1, 10, 0.80), "order": "collection"},
    ]  # fmt: skip
    (tmp_path / "rows.jsonl").write_text("\n".join(json.dumps(r) for r in rows))
    loaded = script.read_rows(tmp_path)
    cell = ("t", "collection", "root", 10)
    assert script.difference(loaded, cell, 10, "accuracy").startswith("+0.300 [")
    assert script.difference(loaded, cell, 10, "accuracy", "uniform").startswith("+0.150 [")
    # pairwise in collection order has a row of its own against uniform pairwise
    lines = script.per_question(loaded, [10], "uniform")
    assert any(line.startswith("| accuracy | pairwise | -0.150 [") for line in lines)
    assert script.difference(loaded, ("t", "uniform", "pairwise", 10), 10, "accuracy") == "-"


def test_an_order_the_grid_lacks_is_refused_in_one_line(script, tmp_path, monkeypatch, capsys):
    (tmp_path / "rows.jsonl").write_text(json.dumps(_row("pairwise", 0, 10, 0.6)))
    (tmp_path / "settings.json").write_text("{}")
    monkeypatch.setattr("sys.argv", ["x", str(tmp_path), "--against-order", "random"])
    with pytest.raises(SystemExit) as stopped:
        script.main()
    assert stopped.value.code == 2
    assert "--against-order 'random': the grid has uniform" in capsys.readouterr().err
