"""scripts/window_open_vs_paper.py: the report's numbers beside Table 7's row, and the
paper's order claimed only where a probability of improvement's interval shows it."""

from __future__ import annotations

import json

import pytest

from support.scripts import load_script


@pytest.fixture(scope="module")
def script():
    return load_script("window_open_vs_paper")


def cell(method: str, iqm: float, n: int = 8) -> dict:
    return dict(task="window-open", method=method, n=n, mean=iqm + 1, std=10.0, iqm=iqm,
                iqm_low=iqm - 5, iqm_high=iqm + 5)  # fmt: skip


def report(improvements: list[tuple[str, str, float, float, float]]) -> dict:
    return {
        "tasks": ["window-open"],
        "table": [
            cell("root", 90.0),
            cell("pairwise", 50.0),
            cell("sequential", 70.0),
            cell("true-reward", 95.0, n=4),
        ],
        "probability_of_improvement": [
            dict(x=x, y=y, p=p, low=low, high=high) for x, y, p, low, high in improvements
        ],
    }


def test_each_row_sets_the_runs_beside_the_papers(script):
    lines = script.comparison(
        report([("root", "pairwise", 0.9, 0.7, 1.0), ("sequential", "pairwise", 0.6, 0.3, 0.9)])
    )
    rows = {line.split(" | ")[0].strip("| "): line for line in lines if line.startswith("| ")}
    assert list(rows)[1:] == ["pairwise", "sequential", "root", "true-reward"]
    assert (
        rows["root"]
        == "| root | 98.6 ± 3.1 | 91.0 ± 10.0 (8 seeds) | 90.0 [85.0, 95.0] | 0.90 [0.70, 1.00] |"
    )
    assert rows["pairwise"].endswith(
        "| 49.4 ± 43.2 | 51.0 ± 10.0 (8 seeds) | 50.0 [45.0, 55.0] | - |"
    )
    assert rows["true-reward"].startswith("| true-reward | - | 96.0 ± 10.0 (4 seeds) |")


def test_the_order_is_claimed_only_where_an_interval_shows_it(script):
    said = script.comparison(
        report(
            [
                ("root", "pairwise", 0.9, 0.7, 1.0),
                ("sequential", "pairwise", 0.6, 0.3, 0.9),
                ("root", "true-reward", 0.4, 0.1, 0.6),
            ]
        )
    )[-1]
    assert "by IQM: root > sequential > pairwise;" in said
    assert said.endswith("lies above 1/2: root over pairwise.")
    none = script.comparison(report([("root", "pairwise", 0.6, 0.4, 0.8)]))[-1]
    assert none.endswith("lies above 1/2: none.")


def test_a_report_without_window_open_or_no_report_is_refused_in_one_line(script, tmp_path):
    other = {"tasks": ["walker_walk"], "table": [], "probability_of_improvement": []}
    with pytest.raises(SystemExit, match="holds no window-open runs"):
        script.comparison(other)
    with pytest.raises(SystemExit, match="run `seqrank report` first"):
        script.main([str(tmp_path / "report.json")])
    (tmp_path / "report.json").write_text(json.dumps(report([])))
    script.main([str(tmp_path / "report.json")])
