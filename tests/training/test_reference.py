"""The shipped true-reward reference: built from true-reward runs, shown beside a run's return."""

from __future__ import annotations

import io
import sys
from types import SimpleNamespace

import numpy as np
from rich.console import Console

from seqrank import reference
from seqrank.cli.train import _print_summary
from support.runs import run, tiny_config
from support.scripts import load_script


def make_reference_script():
    return load_script("make_reference")


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
    share = trainer.run_dir.read_summary()["final_eval_return"] / found.mean
    [line] = [x for x in text.getvalue().splitlines() if "final return / its mean" in x]
    assert f" {share:.2f} " in line
    assert "final success rate" not in text.getvalue()  # DMControl has no success signal

    monkeypatch.setattr(reference, "REFERENCE_FILE", tmp_path / "none.json")
    text = io.StringIO()
    _print_summary(Console(file=text, width=120), trainer.run_dir.read_summary(), trainer.run_dir)
    assert "not measured for these settings" in text.getvalue()


def test_the_shipped_reference_covers_the_main_job_at_its_last_step():
    # `make run` is `seqrank train` with its defaults; on a CPU that is the small preset
    from seqrank.config import resolve_config

    main_job = resolve_config("walker_walk", "small", {"device": "cpu"})
    found = reference.reference_for(main_job.as_dict(), main_job.steps)
    assert found is not None, "no shipped true-reward return for the main job's settings"
    assert found.seeds >= 4 and found.low <= found.mean <= found.high
    assert "results/online-walker-cpu" in found.measured


def test_the_summary_shows_a_success_rate_only_where_the_task_has_one(tmp_path):
    summary = {
        "reward": "true", "steps": 100, "final_eval_return": 10.0, "best_eval_return": 12.0,
        "final_eval_success_rate": 40.0, "sessions": 0, "asked": 0, "inferred": 0,
        "inferred_wrong": 0, "wall_seconds": 60.0, "steps_per_second": 5.0, "eval_curve": [],
    }  # fmt: skip
    shown = {}
    for task in ("button-press", "block:place", "walker_walk", "dmc:cartpole_swingup"):
        text = io.StringIO()
        run_dir = SimpleNamespace(path=tmp_path)
        _print_summary(Console(file=text, width=120), {**summary, "task": task}, run_dir)
        shown[task] = "final success rate" in text.getvalue() and "40%" in text.getvalue()
    assert shown == {
        "button-press": True, "block:place": True, "walker_walk": False,
        "dmc:cartpole_swingup": False,
    }  # fmt: skip
    # a Gymnasium task has a success signal only if it records a success
    for rate, expected in ((0.0, False), (40.0, True)):
        text = io.StringIO()
        hopper = {**summary, "task": "gym:Hopper-v5", "final_eval_success_rate": rate}
        _print_summary(Console(file=text, width=120), hopper, SimpleNamespace(path=tmp_path))
        assert ("final success rate" in text.getvalue()) is expected
