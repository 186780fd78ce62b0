"""Sweep files, the local and Ray engines, retries and resuming."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import pytest

from seqrank.sweeps.engines import Ended, LocalBackend, RayBackend
from seqrank.sweeps.runner import run_sweep
from seqrank.sweeps.spec import expand, load_sweep
from support.sweeps import TINY


def tiny_sweep(out, **extra):
    data = {
        "out": str(out),
        "device": "cpu",
        "tasks": ["dmc:cartpole_swingup"],
        "schemes": ["pairwise", "root"],
        "seeds": 1,
        "overrides": dict(TINY),
    }
    data.update(extra)
    return expand(data)


def tiny_sweep_file(tmp_path):
    """A sweep file of two tiny runs (pairwise, root) into tmp_path/out."""
    overrides = "\n".join(f"{key} = {value}" for key, value in TINY.items())
    spec = tmp_path / "grid.toml"
    spec.write_text(
        f'out = "{tmp_path / "out"}"\ndevice = "cpu"\ntasks = ["dmc:cartpole_swingup"]\n'
        f'schemes = ["pairwise", "root"]\n[overrides]\n{overrides}\n'
    )
    return spec


def test_expansion_covers_the_grid_with_names_and_settings(tmp_path):
    sweep = expand(
        {
            "tasks": ["walker_walk", "cheetah_run"],
            "schemes": ["pairwise", "sequential", "root"],
            "teachers": ["oracle", "mistake"],
            "seeds": [0, 4],
            "device": "cpu",
            "overrides": {"steps": 100_000},
            "task_overrides": {"cheetah_run": {"max_feedback": 200}},
            "variants": [{"name": "q60", "max_feedback": 60}, {"name": "base"}],
        }
    )
    assert len(sweep.runs) == 2 * 3 * 2 * 2 * 2
    names = {r.name for r in sweep.runs}
    assert "cheetah_run/root_pebble_mistake_q60_seed4" in names
    by_name = {r.name: r.config for r in sweep.runs}
    assert by_name["cheetah_run/root_pebble_mistake_q60_seed4"].max_feedback == 60
    assert by_name["cheetah_run/root_pebble_mistake_base_seed4"].max_feedback == 200
    assert by_name["walker_walk/pairwise_pebble_oracle_base_seed0"].max_feedback == 100  # preset
    assert all(r.config.steps == 100_000 and r.config.scale == "small" for r in sweep.runs)


def test_baselines_add_one_run_per_task_variant_and_seed():
    sweep = expand(
        {
            "tasks": ["walker_walk", "block:place"],
            "schemes": ["pairwise", "root"],
            "teachers": ["oracle", "mistake"],
            "baselines": ["true", "none"],
            "seeds": 2,
            "device": "cpu",
        }
    )
    by_name = {r.name: r.config for r in sweep.runs}
    assert len(sweep.runs) == 2 * (2 * 2 + 2) * 2
    assert by_name["walker_walk/true-reward_seed1"].reward == "true"
    assert by_name["block-place/no-feedback_seed0"].reward == "none"
    assert by_name["walker_walk/root_pebble_mistake_seed1"].reward == "learned"
    only = expand(
        {"tasks": ["walker_walk"], "baselines": ["true"], "seeds": 5, "device": "cpu", "wandb": "p"}
    )
    assert [r.name for r in only.runs] == [f"walker_walk/true-reward_seed{s}" for s in range(5)]
    assert {r.wandb for r in only.runs} == {"p"} and {r.wandb for r in sweep.runs} == {None}


def test_qpa_variants_and_baselines_share_a_sweep_with_one_baseline_run_each():
    sweep = expand(
        {
            "tasks": ["walker_walk"],
            "schemes": ["root"],
            "baselines": ["true"],
            "device": "cpu",
            "overrides": {"hybrid_replay": 0.5},
            "variants": [{"name": "plain"}, {"name": "qpa", "query_episodes": 10}],
        }
    )
    by_name = {r.name: r.config for r in sweep.runs}
    assert sorted(by_name) == [
        "walker_walk/root_pebble_oracle_plain_seed0",
        "walker_walk/root_pebble_oracle_qpa_seed0",
        "walker_walk/true-reward_seed0",
    ]
    qpa, baseline = by_name["walker_walk/root_pebble_oracle_qpa_seed0"], by_name[sweep.runs[2].name]
    assert (qpa.query_episodes, qpa.hybrid_replay) == (10, 0.5)
    assert (baseline.query_episodes, baseline.hybrid_replay) == (0, 0.0)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"tasks": ["walker_walk"], "schemes": ["root"], "wandb": 3}, "wandb must be a project"),
        (
            {"tasks": ["walker_walk"], "schemes": ["root"], "overrides": {"device": "cuda"}},
            "unknown setting 'device'; .* device at the top level",
        ),
        ({"tasks": ["walker_walk"], "baselines": ["oracle"]}, "unknown baseline 'oracle'; "),
        ({"tasks": ["walker_walk"], "baselines": ["learned"]}, "accepted: true, none"),
        ({"tasks": ["walker_walk"], "baselines": ["true", "true"]}, "lists a name twice"),
        ({"tasks": ["walker_walk"], "baselines": "true"}, "baselines must be a list"),
        ({"tasks": ["walker_walk"]}, "schemes is required"),
        ({"schemes": ["root"]}, "tasks is required"),
        ({"tasks": [], "schemes": ["root"]}, "tasks must be a non-empty list"),
        ({"tasks": ["walker_walk"], "schemes": ["root", "root"]}, "lists a name twice"),
        ({"tasks": ["walker_walk"], "schemes": ["best"]}, "unknown scheme 'best'"),
        ({"tasks": ["walkr"], "schemes": ["root"]}, "unknown task 'walkr'"),
        ({"tasks": ["walker_walk"], "schemes": ["root"], "seeds": 0}, "at least 1"),
        ({"tasks": ["walker_walk"], "schemes": ["root"], "seeds": [1, 1]}, "distinct"),
        ({"tasks": ["walker_walk"], "schemes": ["root"], "retries": -1}, "retries"),
        ({"tasks": ["walker_walk"], "schemes": ["root"], "engine": "x"}, "unknown key 'engine'"),
        (
            {"tasks": ["walker_walk"], "schemes": ["root"], "overrides": {"stepz": 1}},
            "unknown setting 'stepz'",
        ),
        (
            {"tasks": ["walker_walk"], "schemes": ["root"], "overrides": {"steps": 1.5}},
            "steps = 1.5 is not an int",
        ),
        (
            {"tasks": ["walker_walk"], "schemes": ["root"], "overrides": {"seed": 3}},
            "sweep axes",
        ),
        (
            {"tasks": ["walker_walk"], "schemes": ["root"], "task_overrides": {"hopper_hop": {}}},
            "names a task not in tasks",
        ),
        (
            {"tasks": ["walker_walk"], "schemes": ["root"], "variants": [{"max_feedback": 2}]},
            "needs a name",
        ),
        (
            {"tasks": ["walker_walk"], "schemes": ["root"], "overrides": {"max_feedback": 0}},
            "max_feedback must be a whole number from 1 to 2147483647, got 0",
        ),
        (
            {"tasks": ["walker_walk"], "schemes": ["root"], "overrides": {"precision": "bf16"}},
            "precision 'bf16' needs the fast path",  # path auto on a CPU is the reference
        ),
        (  # teachers with nothing to teach: only the baselines would run, without a word
            {"tasks": ["walker_walk"], "teachers": ["mistake"], "baselines": ["true"]},
            "teachers are given but no schemes",
        ),
    ],
)
def test_bad_sweep_files_name_the_problem(data, message):
    with pytest.raises(ValueError, match=message):
        expand({"device": "cpu", **data})


def test_sweep_file_must_exist_and_be_toml(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        load_sweep(tmp_path / "none.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("tasks = [")
    with pytest.raises(ValueError, match="not valid TOML"):
        load_sweep(bad)


def test_local_engine_runs_skips_resumes_and_reports_failures(tmp_path):
    sweep = tiny_sweep(tmp_path / "sweep")
    status = run_sweep(sweep, LocalBackend(2))
    assert {(r.state, r.outcome) for r in status.runs.values()} == {("finished", "trained")}
    summaries = {
        r.name: json.loads((sweep.out / "runs" / r.name / "summary.json").read_text())
        for r in sweep.runs
    }
    assert {s["scheme"] for s in summaries.values()} == {"pairwise", "root"}
    assert all(s["asked"] == 20 for s in summaries.values())
    # a second start redoes nothing; a run killed before it finished resumes
    killed = sweep.out / "runs" / sweep.runs[1].name
    (killed / "summary.json").unlink()
    stamp = os.stat(sweep.out / "runs" / sweep.runs[0].name / "summary.json").st_mtime_ns
    status = run_sweep(sweep, LocalBackend(2))
    assert status.runs[sweep.runs[0].name].outcome == "skipped"
    assert status.runs[sweep.runs[1].name].outcome == "resumed"
    assert os.stat(sweep.out / "runs" / sweep.runs[0].name / "summary.json").st_mtime_ns == stamp
    recorded = json.loads((sweep.out / "sweep.json").read_text())
    assert recorded["counts"] == {"finished": 2}
    assert sorted(r["outcome"] for r in recorded["runs"]) == ["resumed", "skipped"]


def test_a_failed_runs_error_reads_the_same_from_every_engine():
    """Type name and first line, whatever the engine (the local pool and Ray used to differ:
    `seqrank.errors.SettingError: ...` against `SettingError: ...`)."""
    from seqrank.errors import SettingError, setting
    from seqrank.sweeps.engines import failure_text

    marked = SettingError(f"{setting('knn_k')} 5 must be smaller than {setting('seed_steps')} 1")
    assert failure_text(marked) == "SettingError: knn_k 5 must be smaller than seed_steps 1"
    assert failure_text(RuntimeError("out of memory\nat line 3")) == "RuntimeError: out of memory"
    assert failure_text(KeyError()) == "KeyError"


def test_failures_are_retried_then_reported(tmp_path):
    sweep = tiny_sweep(tmp_path / "sweep", retries=2)
    broken = sweep.runs[0]
    (sweep.out / "runs" / broken.name).mkdir(parents=True)
    (sweep.out / "runs" / broken.name / "config.json").write_text("{not json")
    status = run_sweep(sweep, LocalBackend(2))
    failed = status.runs[broken.name]
    assert failed.state == "failed" and failed.attempts == 3 and "JSON" in failed.error
    assert status.runs[sweep.runs[1].name].state == "finished"
    assert json.loads((sweep.out / "sweep.json").read_text())["counts"] == {
        "failed": 1,
        "finished": 1,
    }


def test_ray_engine_runs_a_tiny_sweep_and_cleans_up(tmp_path, monkeypatch):
    pytest.importorskip("ray")
    import ray

    # a throwaway local cluster: no token file in ~/.ray, session files in a short temp dir
    # (Ray's socket paths must stay under 108 bytes)
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    monkeypatch.setenv("RAY_USAGE_STATS_ENABLED", "0")
    temp = Path(tempfile.mkdtemp(prefix="ray", dir="/tmp"))
    try:
        sweep = tiny_sweep(tmp_path / "sweep")
        status = run_sweep(sweep, RayBackend(None, 2, 1.0, 0.0, temp))
        assert {r.state for r in status.runs.values()} == {"finished"}
        assert not ray.is_initialized()
        assert all((sweep.out / "runs" / r.name / "summary.json").exists() for r in sweep.runs)
        for _ in range(100):  # Ray's own processes (they name the session dir) are gone
            if not processes_mentioning(str(temp)):
                break
            time.sleep(0.1)
        assert processes_mentioning(str(temp)) == []
    finally:
        shutil.rmtree(temp, ignore_errors=True)
    assert not temp.exists()


def processes_mentioning(text: str) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if text.encode() in (entry / "cmdline").read_bytes():
                    found.append(int(entry.name))
            except OSError:
                continue
    return found


BLOCK_SWEEP = """
name = "kill"
out = "{out}"
device = "cpu"
tasks = ["block:place"]
schemes = ["pairwise", "root"]
seeds = 1
[overrides]
steps = 3000
max_feedback = 40
reward_batch = 20
eval_every = 500
checkpoint_every = 500
"""


def test_a_killed_sweep_command_resumes_without_redoing_finished_runs(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    spec = tmp_path / "kill.toml"
    out = tmp_path / "out"
    spec.write_text(BLOCK_SWEEP.format(out=out))
    command = [sys.executable, "-m", "seqrank", "sweep", str(spec), "--workers", "1"]
    listed = subprocess.run([*command, "--dry-run"], capture_output=True, text=True, check=True)
    names = [line.split()[0] for line in listed.stdout.splitlines()]
    assert all(line.endswith("(new)") for line in listed.stdout.splitlines())
    assert names == [
        "block-place/pairwise_pebble_oracle_seed0",
        "block-place/root_pebble_oracle_seed0",
    ]
    first, second = (out / "runs" / n for n in names)
    process = subprocess.Popen(
        command, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + 240
        while not (first / "summary.json").exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        while not (second / "metrics.jsonl").exists() and time.monotonic() < deadline:
            time.sleep(0.2)
    finally:
        os.killpg(process.pid, signal.SIGKILL)  # the sweep and its worker process
        process.wait(10)
    assert (first / "summary.json").exists() and not (second / "summary.json").exists()
    stamp = (first / "summary.json").stat().st_mtime_ns
    again = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    runs = {r["name"]: r for r in json.loads((out / "sweep.json").read_text())["runs"]}
    assert {r["state"] for r in runs.values()} == {"finished"}
    assert runs[names[0]]["outcome"] == "skipped"
    assert runs[names[1]]["outcome"] in ("resumed", "trained")
    assert (first / "summary.json").stat().st_mtime_ns == stamp
    assert json.loads((second / "summary.json").read_text())["steps"] == 3000


def test_sweep_command_rejects_bad_input(tmp_path, capsys):
    from seqrank.cli import main

    assert main(["sweep", str(tmp_path / "none.toml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["sweep", str(tmp_path / "x.toml"), "--workers", "0"]) == 2
    assert "argument --workers: 0 is out of range" in capsys.readouterr().err
    assert main(["sweep", str(tmp_path / "x.toml"), "--ray-address", "auto"]) == 2
    assert "--ray-address is a Ray setting: add --engine ray" in capsys.readouterr().err


class RecordingBackend:
    """Runs nothing: records what the sweep submits and reports each run trained."""

    def __init__(self):
        self.submitted, self.pending = [], []

    def submit(self, run, path, token):
        self.submitted.append(run.name)
        self.pending.append(run.name)
        return run.name

    def started(self):
        return []

    def ended(self, timeout):
        result = {"status": "trained", "summary": {"final_eval_return": 1.0}}
        return [Ended(self.pending.pop(0), result=result)]

    def cancel(self, handle):
        return False

    def stop(self):
        pass

    def close(self):
        pass


def test_a_changed_sweep_file_names_the_runs_it_changed_and_reruns_them_when_asked(
    tmp_path, monkeypatch, capsys
):
    from dataclasses import replace

    from seqrank.cli import main
    from seqrank.dirs import DirLock
    from seqrank.training.runs import RunDir

    spec = tiny_sweep_file(tmp_path)
    sweep = load_sweep(spec)
    changed, same = sweep.runs  # finished runs: one made before the file changed
    for planned, config in (
        (changed, replace(changed.config, max_feedback=10)),
        (same, same.config),
    ):
        run = RunDir.create(sweep.out / "runs" / planned.name, config, "cpu")
        run.write_summary({"final_eval_return": 0.0})
        run.release()
    assert main(["sweep", str(spec)]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"1 runs in {sweep.out / 'runs'} were made with other settings than {spec}" in err
    assert f"{changed.name} (max_feedback 10 -> 20)" in err and "--rerun-changed" in err

    assert main(["sweep", str(spec), "--dry-run"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert listed == [
        f"{changed.name}  (changed: max_feedback 10 -> 20)",
        f"{same.name}  (finished)",
    ]

    with DirLock(sweep.out, "sweep folder"):  # another sweep of this folder is running
        assert main(["sweep", str(spec), "--rerun-changed"]) == 2
        assert f"sweep folder {sweep.out} is in use" in capsys.readouterr().err

    backend = RecordingBackend()
    monkeypatch.setattr("seqrank.cli.sweep._backend", lambda args: backend)
    assert main(["sweep", str(spec), "--rerun-changed"]) == 0
    assert "1 changed runs moved to" in capsys.readouterr().err
    assert backend.submitted == [changed.name, same.name]
    assert not (sweep.out / "runs" / changed.name).exists()
    (moved,) = (sweep.out / "replaced").glob(f"*/{changed.name}")
    assert json.loads((moved / "config.json").read_text())["max_feedback"] == 10


def test_sigterm_to_the_sweep_process_alone_stops_its_runs_with_a_checkpoint(tmp_path):
    """`kill PID` of the sweep (not its process group) reaches the workers: the training
    run stops at an episode end with a checkpoint, the queued run never starts, and the
    command exits 143."""
    import contextlib
    import signal
    import subprocess
    import sys

    from seqrank.dirs import DirLock

    spec = tmp_path / "term.toml"
    out = tmp_path / "out"
    spec.write_text(BLOCK_SWEEP.format(out=out).replace("steps = 3000", "steps = 200000"))
    command = [sys.executable, "-m", "seqrank", "sweep", str(spec), "--workers", "1"]
    process = subprocess.Popen(
        command, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    first = out / "runs" / "block-place" / "pairwise_pebble_oracle_seed0"
    second = out / "runs" / "block-place" / "root_pebble_oracle_seed0"
    try:
        deadline = time.monotonic() + 240
        while not (first / "metrics.jsonl").exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert (first / "metrics.jsonl").exists(), "the first run never started"
        process.send_signal(signal.SIGTERM)
        _, stderr = process.communicate(timeout=120)
    finally:
        with contextlib.suppress(ProcessLookupError):  # whatever is left of the group
            os.killpg(process.pid, signal.SIGKILL)
        process.wait(10)
    assert process.returncode == 143, stderr
    assert b"interrupted" in stderr
    assert (first / "checkpoint.pt").exists() and not (first / "summary.json").exists()
    with DirLock(first, "run directory"):  # the worker has let go of the run
        pass
    assert not (second / "metrics.jsonl").exists()


def test_runs_start_seed_by_seed_so_a_stopped_sweep_leaves_every_method_the_same_seeds():
    sweep = expand(
        {
            "tasks": ["walker_walk"],
            "schemes": ["pairwise", "root"],
            "baselines": ["true"],
            "seeds": [3, 1],
            "device": "cpu",
        }
    )
    assert [r.name for r in sweep.runs] == [
        "walker_walk/pairwise_pebble_oracle_seed3",
        "walker_walk/root_pebble_oracle_seed3",
        "walker_walk/true-reward_seed3",
        "walker_walk/pairwise_pebble_oracle_seed1",
        "walker_walk/root_pebble_oracle_seed1",
        "walker_walk/true-reward_seed1",
    ]


def test_runs_saved_before_a_crowd_default_changed_are_kept_and_resume(tmp_path, capsys):
    """A one-teacher run never reads the crowd's settings: a default changed since it was
    saved (crowd_weighting none -> drop) neither marks it changed nor stops its resume."""
    from dataclasses import replace

    from seqrank.choices import CrowdWeighting
    from seqrank.cli import main
    from seqrank.training.runs import RunDir

    spec = tiny_sweep_file(tmp_path)
    sweep = load_sweep(spec)
    finished, unfinished = sweep.runs
    assert finished.config.crowd_weighting is not CrowdWeighting.NONE
    for planned in sweep.runs:
        old = replace(planned.config, crowd_weighting=CrowdWeighting.NONE)
        run = RunDir.create(sweep.out / "runs" / planned.name, old, "cpu")
        if planned is finished:
            run.write_summary({"final_eval_return": 0.0})
        run.release()
    assert main(["sweep", str(spec), "--workers", "1"]) == 0, capsys.readouterr().err
    runs = {r["name"]: r for r in json.loads((sweep.out / "sweep.json").read_text())["runs"]}
    assert runs[finished.name]["outcome"] == "skipped"
    assert runs[unfinished.name]["state"] == "finished"
    assert (sweep.out / "runs" / unfinished.name / "summary.json").is_file()
