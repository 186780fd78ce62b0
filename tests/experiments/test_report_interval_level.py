"""`seqrank report`'s 95% bootstrap interval, against the bootstrap distribution worked out
exactly: with six runs there are 6^6 equally likely resamples, so the 2.5% and 97.5%
points of the IQM over them can be counted without sampling."""

from __future__ import annotations

import itertools
import json

import numpy as np
from scipy import stats

from seqrank.cli import main

RETURNS = (0.0, 30.0, 90.0, 270.0, 810.0, 990.0)


def finished_run(directory, seed: int, final_return: float, scheme: str = "root") -> None:
    directory.mkdir(parents=True)
    config = {"task": "walker_walk", "scheme": scheme, "backbone": "pebble", "teacher": "oracle"}
    config.update(reward="learned", seed=seed, steps=1000, scale="small")
    (directory / "config.json").write_text(json.dumps(config))
    rows = [
        {"step": 1000, "kind": "eval", "eval_return": final_return, "eval_success_rate": 0.0},
        {"step": 1000, "kind": "feedback", "total_asked": 10, "total_pairs": 14},
    ]
    (directory / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    (directory / "summary.json").write_text(json.dumps({"final_eval_return": final_return}))


def exact_bootstrap_quantiles(values: tuple[float, ...], levels: list[float]) -> np.ndarray:
    """Quantiles of the IQM over every resample with replacement (IQM: 25% trimmed mean)."""
    v = np.asarray(values)
    every = np.array(list(itertools.product(range(len(v)), repeat=len(v))))
    return np.quantile(stats.trim_mean(v[every], 0.25, axis=1), levels)


def test_the_task_tables_interval_is_the_95_percent_one(tmp_path):
    for seed, value in enumerate(RETURNS):
        finished_run(tmp_path / "runs" / f"root_{seed}", seed, value)
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "runs"), "--bootstrap", "20000", "--out", str(out)]) == 0
    (cell,) = json.loads((out / "report.json").read_text())["table"]
    low_band = exact_bootstrap_quantiles(RETURNS, [0.02, 0.03])
    high_band = exact_bootstrap_quantiles(RETURNS, [0.97, 0.98])
    # the bands are narrow enough that a 90% or 99% interval falls outside them
    assert exact_bootstrap_quantiles(RETURNS, [0.05])[0] > low_band[1]
    assert exact_bootstrap_quantiles(RETURNS, [0.95])[0] < high_band[0]
    assert low_band[0] <= cell["iqm_low"] <= low_band[1]
    assert high_band[0] <= cell["iqm_high"] <= high_band[1]


def test_a_method_with_one_run_gets_no_interval_rather_than_a_zero_wide_one(tmp_path):
    finished_run(tmp_path / "runs" / "root_0", 0, 300.0)
    for seed, value in enumerate((100.0, 200.0, 400.0)):
        finished_run(tmp_path / "runs" / f"pairwise_{seed}", seed, value, "pairwise")
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "runs"), "--bootstrap", "200", "--out", str(out)]) == 0
    report = json.loads((out / "report.json").read_text())
    cells = {c["method"]: c for c in report["table"]}
    assert cells["root"]["iqm_low"] is None and cells["root"]["iqm_high"] is None
    low, high = cells["pairwise"]["iqm_low"], cells["pairwise"]["iqm_high"]
    assert 100.0 <= low < high <= 400.0
    aggregate = {a["method"]: a for a in report["aggregate_iqm"]}
    assert aggregate["root"]["low"] is None and aggregate["pairwise"]["low"] is not None
    assert all(p["low"] is None for p in report["probability_of_improvement"])  # root in each
    assert "| walker_walk | root | 300.0 | none (one run) |" in (out / "report.md").read_text()
