"""`seqrank offline train`, `label offline` and `reward-bench pool --from-dataset` refuse
what they cannot use in one line, before anything is printed or made: labels of another
task, numbers out of range, empty paths, budgets beyond the dataset (naming the flags and
the largest accepted), `--steps` beside a dataset; a true-reward run records no
learned-reward settings, and progress without a terminal shows each evaluation."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from seqrank.cli import main
from seqrank.offline.launch import start_new
from seqrank.offline.settings import LEARNED_ONLY, OfflineConfig
from seqrank.training.loop import RunStopped
from support.offline import LINE, write_dataset

TINY = {"steps": 60, "eval_every": 30, "eval_episodes": 1, "hidden": 16, "batch": 32,
        "log_every": 20, "device": "cpu"}  # fmt: skip


def flags(settings: dict[str, object]) -> list[str]:
    return [part for k, v in settings.items() for part in (f"--{k.replace('_', '-')}", str(v))]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("data") / "line", episodes=20, seed=0)


@pytest.fixture(scope="module")
def labels(dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """20 root answers over the line dataset's segments (10 steps), as a label file."""
    from seqrank.offline.labelling import label_dataset, save_labels
    from seqrank.offline.minari_io import load_dataset

    data = load_dataset(str(dataset))
    asked = label_dataset(data, "root", "oracle", 20, 10, 10)
    path = tmp_path_factory.mktemp("labels") / "labels.jsonl"
    save_labels(asked, data, path, "root", "oracle", 10)
    return path


def stopped_at_40(out: Path, config: OfflineConfig) -> None:
    """A new offline run in `out`, stopped (as by Ctrl-C) once 40 updates are made."""
    started = start_new(out, config)

    class StopAt:
        def is_set(self) -> bool:
            return started.trainer.counters.step >= 40

    started.trainer.stop_requested = StopAt()
    with pytest.raises(RunStopped):
        started.trainer.train()
    started.run.release()


def refused(command: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    code = main(command)
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    return err


def test_labels_recorded_on_another_task_are_refused_before_any_labelling(
    dataset, labels, tmp_path, capsys
):
    lines = labels.read_text().splitlines()
    header = json.loads(lines[0])
    assert header["task"] == "support.sb3_envs:make_line"
    other = tmp_path / "other.jsonl"
    moved = json.dumps({**header, "task": "dmc:cartpole_swingup"})
    other.write_text("\n".join([moved, *lines[1:]]) + "\n")
    out = tmp_path / "runs" / "run"
    err = refused(["offline", "train", "--dataset", str(dataset), "--out", str(out),
                   "--reward", "learned", "--teacher", f"replay:{other}", *flags(TINY)],
                  capsys)  # fmt: skip
    assert f"label file {other} was recorded on dmc:cartpole_swingup, not on the dataset's " \
        "task support.sb3_envs:make_line" in err, err  # fmt: skip
    assert "labelling" not in err and not (tmp_path / "runs").exists()


BOUNDS = {
    "steps": (["--steps", "99999999999999999999"], "--steps must be a whole number from 1 to "
              "1000000000, got 99999999999999999999"),
    "eval episodes": (["--eval-episodes", "10001"], "--eval-episodes must be a whole number "
                      "from 1 to 10000, got 10001"),
    "hidden": (["--hidden", "5000"], "--hidden must be a whole number from 1 to 4096, got 5000"),
    "batch": (["--batch", "100000"], "--batch 100000 is more than the 1000 transitions of "
              "dataset {dataset}; accepted: 1 to 1000"),
    "empty dataset": (["--dataset", ""], "--dataset must name a dataset, got an empty value"),
    "empty out": (["--out", ""], "argument --out: an empty path names no run directory"),
    "budget": (["--reward", "learned", "--scheme", "pairwise", "--max-feedback", "5000",
                "--segment-length", "10"],
               "a budget of 5000 pairwise questions (--max-feedback 5000, --session-questions "
               "25) "
               "needs 10000 segments of 10 steps; dataset line-v0 holds 820 distinct ones (20 "
               "episodes, 1000 steps); accepted: --max-feedback 1 to 410, or a larger dataset"),
}  # fmt: skip


@pytest.mark.parametrize("case", list(BOUNDS))
def test_numbers_out_of_range_and_empty_paths_are_refused(
    case, dataset, tmp_path, monkeypatch, capsys
):
    options, text = BOUNDS[case]
    monkeypatch.chdir(tmp_path)
    settings = {**TINY, "batch": 32}
    given = {options[i]: options[i + 1] for i in range(0, len(options), 2)}
    command = ["offline", "train", "--dataset", str(dataset), "--out", "runs/run",
               *[part for k, v in settings.items() if f"--{k.replace('_', '-')}" not in given
                 for part in (f"--{k.replace('_', '-')}", str(v))], *options]  # fmt: skip
    err = refused(command, capsys)
    assert text.format(dataset=dataset) in err, err
    assert list(tmp_path.iterdir()) == []


def test_a_budget_beyond_the_replay_file_names_the_accepted_range(
    dataset, labels, tmp_path, capsys
):
    err = refused(["offline", "train", "--dataset", str(dataset), "--out", str(tmp_path / "r"),
                   "--reward", "learned", "--teacher", f"replay:{labels}", "--max-feedback",
                   "30", *flags(TINY)], capsys)  # fmt: skip
    assert "--max-feedback 30 is more than the 20 answers" in err
    assert "accepted: 1 to 20" in err


def test_label_offline_names_its_flags_and_the_sessions_the_dataset_holds(tmp_path, capsys):
    from support.datasets import write_datasets

    data = write_datasets(tmp_path / "data")["dataset"]  # 2 episodes of 30 steps: 42 of 10
    err = refused(["label", "offline", "--port", "0", "--dataset", data, "--segment-length",
                   "10", "--questions", "5", "--sessions", "100", "--out",
                   str(tmp_path / "labels")], capsys)  # fmt: skip
    assert "(--questions 5 x --sessions 100) needs" in err, err
    assert "accepted: --sessions 1 to " in err and "with --questions 5" in err, err
    err = refused(["label", "offline", "--port", "0", "--dataset", data, "--segment-length",
                   "10", "--questions", "50", "--out", str(tmp_path / "labels")],
                  capsys)  # fmt: skip
    assert "accepted: --questions 1 to " in err and "with --sessions 1" in err, err
    assert not (tmp_path / "labels").exists()


def test_a_true_reward_run_records_no_learned_settings_and_an_old_one_resumes(
    dataset, tmp_path, capsys
):
    out = tmp_path / "run"
    stopped_at_40(out, OfflineConfig(str(dataset), task=LINE, **TINY))
    config = json.loads((out / "config.json").read_text())
    assert {name: config[name] for name in LEARNED_ONLY} == dict.fromkeys(LEARNED_ONLY)
    # a run written before: its config.json records the learned-reward defaults
    old = {**config, **{name: getattr(OfflineConfig("x"), name) for name in LEARNED_ONLY}}
    (out / "config.json").write_text(json.dumps(old))
    assert main(["offline", "train", "--resume", str(out), "--quiet"]) == 0, capsys.readouterr()
    assert json.loads((out / "summary.json").read_text())["steps"] == 60
    (out / "config.json").write_text(json.dumps(config))  # as this version writes it
    assert main(["report", str(tmp_path)]) == 0, capsys.readouterr().err
    assert "| support.sb3_envs:make_line | true-reward |" in capsys.readouterr().out


def test_pool_from_a_dataset_refuses_steps(tmp_path, capsys):
    from support.datasets import write_datasets

    data = write_datasets(tmp_path / "data", episodes=12)["dataset"]
    pool = tmp_path / "pool.npz"
    command = ["reward-bench", "pool", "--from-dataset", data, "--out", str(pool)]
    assert main(command) == 0, capsys.readouterr().err  # without --steps: the pool is made
    pool.unlink()
    capsys.readouterr()
    err = refused([*command, "--steps", "10"], capsys)
    assert "--steps 10 trains a run for the pool" in err and "leave out --steps" in err
    assert not pool.exists()


@pytest.mark.parametrize(
    ("steps", "every", "lines"),
    [(150, 150, ["update 150/150"]), (60, 30, ["update 30/60", "update 60/60"])],
)
def test_progress_without_a_terminal_shows_each_evaluation_and_the_end(
    steps, every, lines, dataset, tmp_path, capsys
):
    settings = {**TINY, "steps": steps, "eval_every": every, "log_every": 50}
    code = main(["offline", "train", "--dataset", str(dataset), "--out", str(tmp_path / "run"),
                 *flags(settings)])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 0, err
    assert [line.split(" |")[0] for line in err.splitlines() if line.startswith("update")] == lines


def test_report_names_the_task_of_a_run_made_without_one(dataset, tmp_path, capsys):
    """An offline run made without `--task` records none: the report reads its dataset's
    (the run unfinished) and then its summary's (finished; its dataset gone)."""
    out = tmp_path / "runs" / "run"
    stopped_at_40(out, OfflineConfig(str(dataset), **TINY))
    assert json.loads((out / "config.json").read_text())["task"] is None
    unfinished = ["report", str(tmp_path / "runs"), "--include-unfinished"]
    assert main(unfinished) == 0, capsys.readouterr().err
    assert "support.sb3_envs:make_line" in capsys.readouterr().out
    assert main(["offline", "train", "--resume", str(out), "--quiet"]) == 0, capsys.readouterr()
    config = json.loads((out / "config.json").read_text())
    (out / "config.json").write_text(json.dumps({**config, "dataset": str(tmp_path / "gone")}))
    assert main(["report", str(tmp_path / "runs")]) == 0, capsys.readouterr().err
    assert "support.sb3_envs:make_line" in capsys.readouterr().out
