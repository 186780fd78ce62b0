"""Baseline runs in sweeps: planned once per task and seed whatever the variants do to the
settings that never reach them, never marked changed by such an edit, and taken over from a
folder where an earlier version planned them under a variant's name."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from seqrank.cli import main
from seqrank.sweeps.spec import load_sweep
from seqrank.training.runs import RunDir
from support.sweeps import TINY

TASK = "dmc:cartpole_swingup"
FOLDER = "dmc-cartpole_swingup"


def write_spec(path: Path, out: Path, overrides: dict, variants: str = "", seeds: int = 1) -> Path:
    settings = "\n".join(f"{key} = {json.dumps(value)}" for key, value in overrides.items())
    path.write_text(
        f'out = "{out}"\ndevice = "cpu"\ntasks = ["{TASK}"]\nschemes = ["root"]\n'
        f'baselines = ["true", "none"]\nseeds = {seeds}\n[overrides]\n{settings}\n{variants}'
    )
    return path


def listed(spec: Path, capsys) -> dict[str, str]:
    """`seqrank sweep --dry-run`: each planned run's name and what the sweep would do."""
    assert main(["sweep", str(spec), "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    return dict(line.split("  ", 1) for line in lines)


def finish(path: Path, config) -> None:
    run = RunDir.create(path, config, "cpu")
    run.write_summary({"final_eval_return": 1.0})
    run.release()


class InProcess:
    """Runs each run's `train_run` at once in this process (a finished run is skipped)."""

    def __init__(self):
        self.results = []

    def submit(self, run, path, token):
        from seqrank.sweeps.engines import Ended, train_run

        self.results.append(Ended(run.name, result=train_run(str(path), run.config.as_dict(), 1)))
        return run.name

    def started(self):
        return []

    def ended(self, timeout):
        done, self.results = self.results, []
        return done

    def cancel(self, handle):
        return False

    def stop(self):
        pass

    def close(self):
        pass


BUDGETS = """
[[variants]]
name = "q10"
max_feedback = 10
[[variants]]
name = "q20"
max_feedback = 20
reward_epochs = 3
[[variants]]
name = "ensemble5"
reward_ensemble = 5
[[variants]]
name = "warm"
warm_start = 1
reward_learner = "rime"
rime_min_epochs = 3
[[variants]]
name = "short"
unsup_steps = 600
"""


def test_a_budget_sweep_plans_each_baseline_once_per_task_and_seed(tmp_path, capsys):
    """Budget, reward training and learner variants (RIME's warm start among them: a
    baseline fits its reward model to nothing) leave one true-reward and one no-feedback run
    per seed; a variant that changes what the no-feedback run uses (its untrained ensemble,
    pre-training length) gets one of its own."""
    spec = write_spec(tmp_path / "budgets.toml", tmp_path / "out", TINY, BUDGETS, seeds=2)
    baselines = [n for n in listed(spec, capsys) if "root_" not in n]
    assert sorted(baselines) == sorted(
        f"{FOLDER}/{name}_seed{seed}"
        for seed in (0, 1)
        for name in (
            "true-reward",
            "no-feedback",
            "no-feedback_ensemble5",
            "no-feedback_short",
        )
    )


def test_editing_a_setting_no_baseline_uses_leaves_its_runs_finished(tmp_path, capsys):
    spec = write_spec(tmp_path / "grid.toml", tmp_path / "out", TINY)
    sweep = load_sweep(spec)
    for planned in sweep.runs:
        finish(sweep.out / "runs" / planned.name, planned.config)
    more = {**TINY, "max_feedback": 40, "reward_batch": 20, "reward_epochs": 3}
    write_spec(spec, tmp_path / "out", {**more, "hybrid_replay": 0.5})
    states = listed(spec, capsys)
    learned = states.pop(f"{FOLDER}/root_pebble_oracle_seed0")
    for edit in ("max_feedback 20 -> 40", "reward_epochs 5 -> 3", "hybrid_replay 0.0 -> 0.5"):
        assert edit in learned
    assert states == {
        f"{FOLDER}/true-reward_seed0": "(finished)",
        f"{FOLDER}/no-feedback_seed0": "(finished)",
    }
    # pre-training reaches the no-feedback run only
    write_spec(spec, tmp_path / "out", {**TINY, "unsup_steps": 600})
    states = listed(spec, capsys)
    assert states[f"{FOLDER}/true-reward_seed0"] == "(finished)"
    assert states[f"{FOLDER}/no-feedback_seed0"] == "(changed: unsup_steps 900 -> 600)"


def test_a_folder_with_baselines_under_a_variants_name_keeps_them(tmp_path, capsys, monkeypatch):
    """An earlier version planned a baseline under its first variant's name, with every
    setting: that directory is taken over (renamed) when only settings it never used
    differ, and skipped as finished; one whose used settings differ is left alone."""
    variants = '[[variants]]\nname = "q10"\nmax_feedback = 10\n'
    variants += '[[variants]]\nname = "q20"\nmax_feedback = 20\n'
    spec = write_spec(tmp_path / "grid.toml", tmp_path / "out", TINY, variants)
    sweep = load_sweep(spec)
    runs = sweep.out / "runs"
    planned = {r.name: r.config for r in sweep.runs}
    true_reward, no_feedback = (
        planned[f"{FOLDER}/true-reward_seed0"],
        planned[f"{FOLDER}/no-feedback_seed0"],
    )
    finish(runs / FOLDER / "true-reward_q10_seed0", replace(true_reward, max_feedback=10))
    finish(
        runs / FOLDER / "no-feedback_q10_seed0", replace(no_feedback, max_feedback=10, steps=2400)
    )
    states = listed(spec, capsys)
    assert states[f"{FOLDER}/true-reward_seed0"] == (
        "(finished, as dmc-cartpole_swingup/true-reward_q10_seed0: renamed to this)"
    )
    assert states[f"{FOLDER}/no-feedback_seed0"] == "(new)"  # it trained 2400 steps

    backend = InProcess()
    monkeypatch.setattr("seqrank.cli.sweep._backend", lambda args: backend)
    learned = [name for name in planned if "root_" in name]
    for name in learned:  # only the baselines are left to run
        finish(runs / name, planned[name])
    capsys.readouterr()
    assert main(["sweep", str(spec)]) == 0
    planned_runs = len(planned)  # two learned runs and two baselines, all finished now
    assert f"sweep grid: {planned_runs} finished; state in " in capsys.readouterr().out
    recorded = {r["name"]: r for r in json.loads((sweep.out / "sweep.json").read_text())["runs"]}
    assert recorded[f"{FOLDER}/true-reward_seed0"]["outcome"] == "skipped"
    assert recorded[f"{FOLDER}/no-feedback_seed0"]["outcome"] == "trained"
    assert not (runs / FOLDER / "true-reward_q10_seed0").exists()
    assert (
        json.loads((runs / FOLDER / "no-feedback_q10_seed0" / "config.json").read_text())["steps"]
        == 2400
    )
