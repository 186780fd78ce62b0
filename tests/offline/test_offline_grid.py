"""scripts/offline_grid.py at test sizes: a dataset made, every arm's IQL run, a report whose
numbers are the runs' own, finished runs left alone, a run without its summary finished
from its checkpoint, and the SAC and dataset commands of a medium-replay grid valid
`seqrank` command lines."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from seqrank.cli import build_parser
from support.offline import LINE, write_dataset
from support.scripts import load_script

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "offline_grid.py"
GRID = f"""
tasks = ["{LINE}"]
seeds = 2
questions = [6]
schemes = ["pairwise", "root"]
[dataset]
sources = ["random"]
episodes = 12
[offline]
steps = 20
eval_every = 10
eval_episodes = 1
hidden = 16
batch = 16
segment_length = 10
session_questions = 6
device = "cpu"
"""


@pytest.fixture(scope="module")
def grid_module():
    return load_script("offline_grid")


@pytest.fixture(scope="module")
def finished_grid(grid_module, tmp_path_factory):
    root = tmp_path_factory.mktemp("grid")
    (root / "grid.toml").write_text(GRID)
    # the line task renders no clips, which `seqrank dataset make` records: made here
    write_dataset(grid_module.Layout(root / "out").dataset(LINE), episodes=12, seed=0)
    code = grid_module.main([str(root / "grid.toml"), "--out", str(root / "out")])
    assert code == 0
    return root


def summaries(out: Path) -> dict[str, dict]:
    return {
        path.parent.name: json.loads(path.read_text())
        for path in sorted((out / "runs").rglob("summary.json"))
    }


def test_every_arm_and_seed_runs_on_the_dataset_made(finished_grid):
    out = finished_grid / "out"
    assert (out / "datasets").is_dir() and len(list((out / "datasets").iterdir())) == 1
    runs = summaries(out)
    arms = ["true", "pairwise-q6", "root-q6"]
    assert sorted(runs) == sorted(f"{arm}_seed{seed}" for arm in arms for seed in (0, 1))
    for name, summary in runs.items():
        assert summary["steps"] == 20 and summary["seed"] == int(name[-1])
        learned = not name.startswith("true")
        assert summary["reward"] == ("learned" if learned else "true")
        if learned:
            assert summary["max_feedback"] == 6 and summary["scheme"] == name.split("-")[0]


def test_the_report_gives_each_arms_mean_of_its_runs_final_returns(finished_grid):
    out = finished_grid / "out"
    report = json.loads((out / "report.json").read_text())
    runs = summaries(out)
    assert report["missing"] == []
    for row in report["rows"]:
        finals = [runs[f"{row['arm']}_seed{s}"]["final_eval_return"] for s in (0, 1)]
        assert row["seeds"] == [0, 1]
        assert row["return"]["values"] == pytest.approx(finals)
        mean, low, high = row["return"]["mean"]
        assert mean == pytest.approx(np.mean(finals))
        # two seeds: the bootstrap draws either run twice or both once
        assert low == pytest.approx(min(finals)) and high == pytest.approx(max(finals))
        assert row["return"]["iqm"][0] == pytest.approx(np.mean(finals))  # IQM of two
    assert "| root-q6 | 2 |" in (out / "report.md").read_text()


def test_a_second_call_leaves_finished_runs_alone_and_finishes_a_stopped_one(
    grid_module, finished_grid, capsys
):
    out = finished_grid / "out"
    stopped = out / "runs" / next((out / "runs").iterdir()).name / "root-q6_seed1"
    before = {p: p.stat().st_mtime_ns for p in (out / "runs").rglob("summary.json")}
    summary = json.loads((stopped / "summary.json").read_text())
    (stopped / "summary.json").unlink()  # as if stopped after its last checkpoint
    code = grid_module.main([str(finished_grid / "grid.toml"), "--out", str(out)])
    assert code == 0
    said = capsys.readouterr().out
    assert said.count("done IQL") == 1 and "root-q6 seed 1" in said
    again = json.loads((stopped / "summary.json").read_text())
    assert again["final_eval_return"] == summary["final_eval_return"]
    for path, mtime in before.items():
        if path.parent != stopped:
            assert path.stat().st_mtime_ns == mtime


def test_kept_records_let_a_grid_continue_on_a_new_machine(grid_module, tmp_path, capsys):
    (tmp_path / "grid.toml").write_text(GRID.replace("seeds = 2", "seeds = 1"))
    first, keep = tmp_path / "first", tmp_path / "kept"
    write_dataset(grid_module.Layout(first).dataset(LINE), episodes=12, seed=0)
    assert grid_module.main([str(tmp_path / "grid.toml"), "--out", str(first),
                             "--keep", str(keep)]) == 0  # fmt: skip
    kept = sorted(p.relative_to(keep) for p in keep.rglob("*") if p.is_file())
    runs = ["true_seed0", "pairwise-q6_seed0", "root-q6_seed0"]
    assert {p.parent.name for p in kept} == set(runs)
    assert {p.name for p in kept} == set(grid_module.RECORDS)  # no checkpoint
    (keep / kept[0].parent / "summary.json").unlink()  # one run not finished when kept
    capsys.readouterr()
    second = tmp_path / "second"  # a new machine: the kept records, no runs, a new dataset
    write_dataset(grid_module.Layout(second).dataset(LINE), episodes=12, seed=0)
    assert grid_module.main([str(tmp_path / "grid.toml"), "--out", str(second),
                             "--keep", str(keep), "--stage", "runs"]) == 0  # fmt: skip
    said = capsys.readouterr().out
    assert "2 finished runs' records restored" in said and said.count("done IQL") == 1
    assert json.loads((second / "report.json").read_text())["missing"] == []
    assert (keep / kept[0].parent / "summary.json").is_file()


def test_runs_finished_before_keep_was_given_are_kept(grid_module, finished_grid, tmp_path):
    keep = tmp_path / "kept"
    code = grid_module.main([str(finished_grid / "grid.toml"), "--out",
                             str(finished_grid / "out"), "--keep", str(keep),
                             "--stage", "runs"])  # fmt: skip
    assert code == 0
    assert len(list(keep.glob("*/*/summary.json"))) == 6


def test_the_report_says_when_a_tasks_runs_trained_on_different_datasets(
    grid_module, finished_grid, tmp_path
):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(finished_grid / "out" / "runs", out / "runs")
    path = next(out.glob("runs/*/root-q6_seed1/summary.json"))
    summary = json.loads(path.read_text())
    same = summary["dataset_digest"]
    code = grid_module.main([str(finished_grid / "grid.toml"), "--out", str(out),
                             "--stage", "report"])  # fmt: skip
    assert code == 0 and "different datasets" not in (out / "report.md").read_text()
    path.write_text(json.dumps({**summary, "dataset_digest": "made-elsewhere"}))
    grid_module.main([str(finished_grid / "grid.toml"), "--out", str(out), "--stage", "report"])
    said = (out / "report.md").read_text()
    assert "trained on 2 different datasets" in said and same in said


def test_a_failed_run_is_reported_and_the_grid_goes_on(grid_module, tmp_path, capsys):
    (tmp_path / "grid.toml").write_text(GRID.replace("steps = 20", "steps = 0"))
    write_dataset(grid_module.Layout(tmp_path / "out").dataset(LINE), episodes=12, seed=0)
    code = grid_module.main([str(tmp_path / "grid.toml"), "--out", str(tmp_path / "out"),
                             "--stage", "runs"])  # fmt: skip
    said = capsys.readouterr().out
    assert code == 1 and said.count("FAILED IQL") == 6
    assert "Not finished yet: 6 runs." in (tmp_path / "out" / "report.md").read_text()


def test_a_stop_asked_for_ends_in_one_line_not_a_traceback(
    grid_module, tmp_path, capsys, monkeypatch
):
    (tmp_path / "grid.toml").write_text(GRID)

    def interrupted(*_args):
        raise KeyboardInterrupt

    monkeypatch.setattr(grid_module, "run_offline", interrupted)
    code = grid_module.main([str(tmp_path / "grid.toml"), "--out", str(tmp_path / "out"),
                             "--stage", "runs"])  # fmt: skip
    said = capsys.readouterr()
    assert code == 130 and "Traceback" not in said.out + said.err
    assert said.out.strip().splitlines()[-1] == (
        "stopped after 0 step(s); the same command continues the grid"
    )


def test_a_medium_replay_grid_plans_valid_sac_and_dataset_commands(grid_module, tmp_path):
    grid_file = tmp_path / "grid.toml"
    grid_file.write_text(
        'tasks = ["button-press-topdown"]\n[dataset]\nruns = 3\nrun_steps = 100000\n'
        'run_settings = { scale = "small" }\n'
    )
    grid, layout = grid_module.Grid.read(grid_file), grid_module.Layout(tmp_path / "out")
    sac = grid_module.sac_argv(grid, layout, "button-press-topdown", 2)
    parsed = build_parser().parse_args(sac)
    assert parsed.steps == 100000 and parsed.seed == 2 and parsed.episodes_kept == 200
    assert parsed.reward == "true" and parsed.scale == "small"
    make = grid_module.dataset_argv(grid, layout, "button-press-topdown")
    parsed = build_parser().parse_args(make)
    assert parsed.out == str(layout.dataset("button-press-topdown"))
    assert parsed.episodes == 600
    assert parsed.source == [f"run:{layout.sac('button-press-topdown', s)}" for s in range(3)]
    (layout.sac("button-press-topdown", 1)).mkdir(parents=True)
    (layout.sac("button-press-topdown", 1) / "config.json").write_text("{}")
    assert grid_module.sac_argv(grid, layout, "button-press-topdown", 1)[:2] == [
        "train",
        "--resume",
    ]


def test_a_played_dataset_is_made_by_the_sources_named(grid_module, tmp_path):
    (tmp_path / "grid.toml").write_text(GRID)
    grid, layout = grid_module.Grid.read(tmp_path / "grid.toml"), grid_module.Layout(tmp_path)
    make = grid_module.dataset_argv(grid, layout, LINE)
    parsed = build_parser().parse_args(make)
    assert parsed.source == ["random"] and parsed.episodes == 12 and parsed.seed == 0


def test_a_grid_file_with_an_unknown_key_or_no_dataset_is_refused(grid_module, tmp_path):
    path = tmp_path / "grid.toml"
    path.write_text('tasks = ["x"]\nsteps = 3\n[dataset]\nruns = 1\n')
    with pytest.raises(ValueError, match="unknown key 'steps'"):
        grid_module.Grid.read(path)
    path.write_text('tasks = ["x"]\n[dataset]\n')
    with pytest.raises(ValueError, match=r"runs \(SAC runs\) or sources"):
        grid_module.Grid.read(path)


def test_the_committed_grid_plans_45_runs_whose_settings_are_valid(grid_module):
    from seqrank.offline.settings import OfflineConfig, validate

    path = SCRIPT.parents[1] / "results" / "offline-metaworld" / "grid.toml"
    grid = grid_module.Grid.read(path)
    jobs = list(grid_module.offline_jobs(grid, grid_module.Layout(Path("out"))))
    assert len(jobs) == 45 and len({run for _, _, run, _ in jobs}) == 45
    for _, dataset, _, settings in jobs:
        validate(OfflineConfig(dataset=str(dataset), **settings))
