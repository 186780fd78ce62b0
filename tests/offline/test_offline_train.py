"""`seqrank offline train` at test sizes: a run from a small dataset made here, its rows and
summary, a stopped run resumed to the same numbers as an uninterrupted one, the learned
reward end to end, and bad input refused in one line with nothing left behind."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import torch

import seqrank
from seqrank.cli import main
from seqrank.offline.launch import start_new
from seqrank.offline.settings import OfflineConfig
from seqrank.training.loop import RunStopped
from support.offline import LINE, write_dataset

TINY = {"steps": 60, "eval_every": 30, "eval_episodes": 2, "hidden": 16, "batch": 32,
        "log_every": 20, "device": "cpu"}  # fmt: skip
TIMING = ("wall_seconds", "updates_per_second")  # differ between two runs of one machine


def flags(settings: dict[str, object]) -> list[str]:
    return [part for k, v in settings.items() for part in (f"--{k.replace('_', '-')}", str(v))]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_dataset(tmp_path_factory.mktemp("data") / "line", episodes=20, seed=0)


def rows(run: Path) -> list[dict[str, object]]:
    lines = (run / "metrics.jsonl").read_text().splitlines()
    return [{k: v for k, v in json.loads(line).items() if k not in TIMING} for line in lines]


def test_a_run_trains_evaluates_and_writes_its_rows_and_summary(dataset, tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["offline", "train", "--dataset", str(dataset), "--out", str(out), "--quiet",
                 *flags(TINY)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert "IQL on its true reward, 60 updates" in capsys.readouterr().out
    kinds = [(row["step"], row["kind"]) for row in rows(out)]
    assert kinds == [(20, "train"), (30, "eval"), (40, "train"), (60, "train"), (60, "eval")]
    train = rows(out)[0]
    assert {"value_loss", "actor_loss", "critic_loss", "weight_mean", "actor_lr"} <= set(train)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["task"] == LINE and summary["reward"] == "true" and summary["steps"] == 60
    assert [step for step, _ in summary["eval_curve"]] == [30, 60]
    assert summary["reward_scale"] == "returns" and summary["dataset_episodes"] == 20
    assert json.loads((out / "config.json").read_text())["dataset"] == str(dataset)
    assert (out / "checkpoint.pt").is_file()


def test_a_task_without_a_success_signal_reports_no_success_rate(tmp_path, capsys):
    """DMControl has no success signal: as `dataset info` gives its dataset's success as
    null, the run's summary does (not 0.0), and the printed summary shows none."""
    from seqrank.offline.make import describe
    from support.datasets import write_datasets

    data = write_datasets(tmp_path / "data")["dataset"]  # dmc:cartpole_swingup
    out = tmp_path / "run"
    short = {**TINY, "steps": 20, "eval_every": 20, "eval_episodes": 1, "batch": 16}
    code = main(["offline", "train", "--dataset", data, "--out", str(out), "--quiet",
                 *flags(short)])  # fmt: skip
    printed = capsys.readouterr().out
    assert code == 0 and "eval return" in printed and "success rate" not in printed
    summary = json.loads((out / "summary.json").read_text())
    assert describe(data)["success_rate"] is None
    assert summary["final_eval_success_rate"] is None
    assert summary["best_eval_success_rate"] is None and summary["success_curve"] is None
    assert summary["final_eval_return"] is not None and len(summary["eval_curve"]) == 1


class StopAt:
    """A stop request that arrives once the trainer has made `step` updates."""

    def __init__(self, step: int):
        self.step, self.trainer = step, None

    def is_set(self) -> bool:
        return self.trainer.counters.step >= self.step


def test_a_stopped_run_resumes_to_the_numbers_of_an_uninterrupted_one(dataset, tmp_path):
    whole = tmp_path / "whole"
    seqrank.offline_train(dataset, whole, **TINY)

    parted = tmp_path / "parted"
    started = start_new(parted, OfflineConfig(str(dataset), **TINY))
    stop = StopAt(45)  # between evaluations: the checkpoint is the stop's own
    stop.trainer = started.trainer
    started.trainer.stop_requested = stop
    with pytest.raises(RunStopped):
        started.trainer.train()
    started.run.release()
    assert not (parted / "summary.json").exists()
    assert main(["offline", "train", "--resume", str(parted), "--quiet"]) == 0

    assert rows(parted) == rows(whole)
    first, second = (json.loads((d / "summary.json").read_text()) for d in (whole, parted))
    assert first["eval_curve"] == second["eval_curve"]
    actors = [torch.load(d / "checkpoint.pt", weights_only=False)["agent"]["actor"]
              for d in (whole, parted)]  # fmt: skip
    assert all(torch.equal(actors[0][k], actors[1][k]) for k in actors[0])


def test_a_finished_run_is_not_trained_again_and_resume_takes_no_settings(
    dataset, tmp_path, capsys
):
    out = tmp_path / "run"
    summary = seqrank.offline_train(dataset, out, **TINY)
    assert seqrank.offline_train(dataset, out, **TINY) == summary  # same settings: returned
    assert main(["offline", "train", "--resume", str(out)]) == 0
    assert "is finished" in capsys.readouterr().err
    assert main(["offline", "train", "--resume", str(out), "--steps", "90"]) == 2
    assert "drop --steps" in capsys.readouterr().err
    with pytest.raises(ValueError, match="other settings"):
        seqrank.offline_train(dataset, out, **{**TINY, "steps": 90})


def test_a_learned_reward_labels_the_dataset_fits_and_trains_on_it(dataset, tmp_path, capsys):
    out = tmp_path / "run"
    learned = {"reward": "learned", "scheme": "root", "teacher": "oracle", "max_feedback": 20,
               "segment_length": 10, "session_questions": 10}  # fmt: skip
    code = main(["offline", "train", "--dataset", str(dataset), "--out", str(out), "--quiet",
                 *flags(learned), *flags(TINY)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    feedback = [row for row in rows(out) if row["kind"] == "feedback"]
    assert len(feedback) == 1 and feedback[0]["step"] == 0 and feedback[0]["questions"] == 20
    assert feedback[0]["total_pairs"] > 20  # root's closure infers pairs beyond those asked
    assert (out / "labels.jsonl").is_file() and (out / "learned_rewards.npy").is_file()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reward"] == "learned" and summary["scheme"] == "root"

    # its labels replayed: the run takes the file's scheme, budget and lengths, and says so
    replay = {"reward": "learned", "teacher": f"replay:{out / 'labels.jsonl'}"}
    again = tmp_path / "replayed"
    code = main(["offline", "train", "--dataset", str(dataset), "--out", str(again), "--quiet",
                 *flags(replay), *flags(TINY)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    config = json.loads((again / "config.json").read_text())
    taken = ("scheme", "max_feedback", "segment_length", "session_questions")
    assert [config[name] for name in taken] == ["root", 20, 10, 10]
    other = tmp_path / "other"
    code = main(["offline", "train", "--dataset", str(dataset), "--out", str(other), "--quiet",
                 *flags({**replay, "scheme": "pairwise"}), *flags(TINY)])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "--scheme pairwise conflicts with the replay file's root" in err
    assert not other.exists()


LEARNED = {"reward": "learned", "scheme": "root", "teacher": "oracle", "max_feedback": 20,
           "segment_length": 10, "session_questions": 10}  # fmt: skip


@pytest.mark.parametrize(
    ("at", "said"),
    [
        ("label_dataset", "interrupted while labelling the dataset, before training began: "
         "removed {out}\n"),
        ("fit_reward", "interrupted while fitting the reward, before training began: removed "
         "{out} and its labels (oracle's; the same command asks again)\n"),
    ],
)  # fmt: skip
def test_ctrl_c_while_the_labels_are_asked_or_fitted(
    at, said, dataset, tmp_path, monkeypatch, capsys
):
    """A first Ctrl-C lets the labels and the fit finish, keeps them and stops the run at
    update 0 (resumable); a second stops at once: the run directory made by the same
    command is removed, and a line says so and what went with it."""
    import signal

    from seqrank.offline import labelling

    real = getattr(labelling, at)

    def first_ctrl_c(*args, **kwargs):
        signal.raise_signal(signal.SIGINT)
        return real(*args, **kwargs)

    command = ["offline", "train", "--dataset", str(dataset), "--quiet", *flags(LEARNED),
               *flags(TINY)]  # fmt: skip
    monkeypatch.setattr(labelling, at, first_ctrl_c)
    kept = tmp_path / "kept"
    assert main([*command, "--out", str(kept)]) == 130
    again = "stopped at update 0, checkpoint saved; continue with: seqrank offline train --"
    assert capsys.readouterr().err.endswith(f"{again}resume {kept}\n")
    assert (kept / "labels.jsonl").is_file() and (kept / "learned_rewards.npy").is_file()

    def second_ctrl_c(*args, **kwargs):
        raise KeyboardInterrupt  # what the second signal raises

    monkeypatch.setattr(labelling, at, second_ctrl_c)
    out = tmp_path / "runs" / "run"
    assert main([*command, "--out", str(out)]) == 130
    assert capsys.readouterr().err.endswith(said.format(out=out))
    assert not (tmp_path / "runs").exists()


BUDGET = {"reward": "learned", "scheme": "pairwise", "max_feedback": 5000}  # 20 segments there
BAD = {  # case -> (options, text the one line must hold); "DATA": the test's dataset
    "missing dataset": ({"dataset": "nothing"}, "no Minari dataset at"),
    "another task": ({"dataset": "DATA", "task": "dmc:cartpole_swingup"}, "is of task"),
    "sizes": ({"dataset": "wide"}, "observations of size 3"),
    "budget": (
        {"dataset": "DATA", **BUDGET},
        "a budget of 5000 pairwise questions (--max-feedback 5000",
    ),
    "segment longer than an episode": (  # the line task's episodes: 50 steps, cut
        {"dataset": "DATA", "reward": "learned", "max_feedback": 5, "segment_length": 51},
        "--segment-length 51 is longer than the shortest episode of dataset line-v0 that ends "
        "without a terminal state (50 steps; a segment is padded only past a terminal state); "
        "accepted: 1 to 50",
    ),
    "setting": ({"dataset": "DATA", "expectile": 1.5}, "--expectile must be"),
    "no dataset": ({}, "--dataset is needed"),
    "learned setting, true reward": (
        {"dataset": "DATA", "scheme": "root"},
        "--scheme acts on a learned reward; --reward true trains on the dataset's own",
    ),
    "a person": (
        {"dataset": "DATA", "reward": "learned", "teacher": "human"},
        "answers on the labelling page: label the dataset there",
    ),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_is_one_line_and_leaves_nothing_behind(case, dataset, tmp_path, capsys):
    options, text = BAD[case]
    if options.get("dataset") == "wide":  # rows wider than the task's observations
        options = {"dataset": write_dataset(tmp_path / "wide", 3, extra_obs=1)}
    elif options.get("dataset") in ("DATA", "nothing"):
        named = dataset if options["dataset"] == "DATA" else tmp_path / "nothing"
        options = {**options, "dataset": named}
    out = tmp_path / "runs" / "run"
    code = main(["offline", "train", "--out", str(out), *flags(options), *flags(TINY)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert text in err and err.startswith("seqrank offline: error:"), err
    assert not (tmp_path / "runs").exists()


def test_a_dataset_that_changed_since_the_run_began_is_refused_on_resume(tmp_path, capsys):
    data = write_dataset(tmp_path / "line", episodes=5, seed=0)
    out = tmp_path / "run"
    started = start_new(out, OfflineConfig(str(data), **TINY))
    stop = StopAt(40)
    stop.trainer = started.trainer
    started.trainer.stop_requested = stop
    with pytest.raises(RunStopped):
        started.trainer.train()
    started.run.release()
    shutil.rmtree(data)
    write_dataset(data, episodes=5, seed=1)
    assert main(["offline", "train", "--resume", str(out), "--quiet"]) == 2
    assert "changed since" in capsys.readouterr().err


def test_the_api_names_an_unknown_setting_before_anything_is_made(dataset, tmp_path):
    with pytest.raises(ValueError, match="unknown setting stepz"):
        seqrank.offline_train(dataset, tmp_path / "run", stepz=10)
    assert not (tmp_path / "run").exists()
