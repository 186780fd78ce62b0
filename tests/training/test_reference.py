"""The shipped true-reward reference: built from true-reward runs, shown beside a run's return."""

from __future__ import annotations

import importlib.util
import io
import sys
from pathlib import Path

import numpy as np
from rich.console import Console

from seqrank import reference
from seqrank.cli.train import _print_summary
from support.runs import run, tiny_config

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "make_reference.py"


def make_reference_script():
    spec = importlib.util.spec_from_file_location("make_reference", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_run_summary_shows_the_measured_true_reward_return_at_its_step_or_says_none(
    tmp_path, monkeypatch
):
    quick = dict(steps=1600, eval_every=800)
    finals = []
    for seed in (1, 2):
        trainer = run(
            tmp_path / "true" / f"s{seed}", tiny_config(reward="true", seed=seed, **quick)
        )
        finals.append(trainer.run_dir.read_summary()["final_eval_return"])
    file = tmp_path / "reference.json"
    monkeypatch.setattr(
        sys, "argv", ["x", str(tmp_path / "true"), "--measured", "here: cmd", "--out", str(file)]
    )
    make_reference_script().main()
    monkeypatch.setattr(reference, "REFERENCE_FILE", file)

    learned = tiny_config(max_feedback=10, **quick)
    found = reference.reference_for(learned.as_dict(), 1600)
    assert found is not None and found.seeds == 2
    assert np.isclose(found.mean, np.mean(finals)) and found.low <= found.mean <= found.high
    assert reference.reference_for(learned.as_dict(), 1200) is None  # no evaluation there
    other = tiny_config(hidden=64, max_feedback=10, **quick).as_dict()
    assert reference.reference_for(other, 1600) is None  # another agent: no comparison

    trainer = run(tmp_path / "learned", learned)
    text = io.StringIO()
    _print_summary(Console(file=text, width=120), trainer.run_dir.read_summary(), trainer.run_dir)
    assert "true-reward agent, same step (measured)" in text.getvalue()
    assert found.describe() in text.getvalue() and "here" in text.getvalue()

    monkeypatch.setattr(reference, "REFERENCE_FILE", tmp_path / "none.json")
    text = io.StringIO()
    _print_summary(Console(file=text, width=120), trainer.run_dir.read_summary(), trainer.run_dir)
    assert "not measured for these settings" in text.getvalue()
