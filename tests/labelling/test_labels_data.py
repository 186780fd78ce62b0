"""Labels as data: JSONL export/import, `--teacher replay:FILE`, online training with a person."""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest
from fastapi.testclient import TestClient

from seqrank.cli import main
from seqrank.feedback.closure import augment
from seqrank.feedback.label_file import read_label_file
from seqrank.labelling.app import ServerOptions, open_hub
from seqrank.labelling.db import LabelDB
from seqrank.labelling.human import HumanSource
from seqrank.labelling.jsonl import export_file, import_file
from seqrank.training.runs import RunDir
from seqrank.training.trainer import Trainer
from seqrank.types import Answer, AnsweredQuestion, Question
from support.pages import Page, page_client
from support.runs import tiny_config

CHOICES = ["left", "right", "equal", "left", "skip", "right", "left", "timeout"]


@pytest.fixture(scope="module")
def label_file(tmp_path_factory):
    """An offline sequential session of 8 questions answered with CHOICES, exported."""
    directory = tmp_path_factory.mktemp("offline")
    page = Page(directory / "labels", "sequential", 8)
    try:
        for choice in CHOICES:
            page.answer(choice)
        page.done.wait(10)
        path = directory / "labels.jsonl"
        export_file(page.hub.db, path)
    finally:
        page.close()
    return path


def test_export_holds_roles_provenance_and_the_answers(label_file):
    labels = read_label_file(label_file)
    assert len(labels.answers) == 8
    assert [a["timed_out"] for a in labels.answers] == [c == "timeout" for c in CHOICES]
    for record, choice in zip(labels.answers, CHOICES, strict=True):
        assert record["defender"] == record["first"] and record["challenger"] == record["second"]
        if choice in ("left", "right"):
            preferred = record[choice]
            assert record["answer"] == ("first" if preferred == record["first"] else "second")
        else:
            assert record["answer"] == {"equal": "equal", "skip": "skip", "timeout": "skip"}[choice]
        segment = labels.segments[record["first"]]
        assert np.asarray(segment["features"]).shape == (50, 6)
        assert np.asarray(segment["states"]).shape[0] == 50


def test_import_round_trips_and_is_idempotent(label_file, tmp_path):
    db = LabelDB.in_dir(tmp_path / "copy")
    assert import_file(db, label_file) == 8
    assert import_file(db, label_file) == 0
    export_file(db, tmp_path / "again.jsonl")
    original, copy = read_label_file(label_file), read_label_file(tmp_path / "again.jsonl")
    keys = ("first", "second", "left", "right", "defender", "answer", "timed_out", "latency_ms")
    assert [[a[k] for k in keys] for a in copy.answers] == [
        [a[k] for k in keys] for a in original.answers
    ]
    changed = tmp_path / "changed.jsonl"
    lines = label_file.read_text().splitlines()
    index = next(i for i, line in enumerate(lines) if '"answer": "equal"' in line)
    lines[index] = lines[index].replace('"answer": "equal"', '"answer": "first"')
    changed.write_text("\n".join(lines))
    with pytest.raises(ValueError, match="in the file but 'equal' in the database"):
        import_file(db, changed)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("", "empty label file"),
        ('{"type": "segment"}', "first line must be"),
        ('{"type": "header", "format": "seqrank-labels", "version": 9}', "format version 9"),
        ('{"type": "header", "format": "seqrank-labels", "version": 1}\n{oops', "line 2: not JSON"),
        (
            '{"type": "header", "format": "seqrank-labels", "version": 1}\n{"type": "vote"}',
            "unknown record type 'vote'",
        ),
        (
            '{"type": "header", "format": "seqrank-labels", "version": 1}\n'
            '{"type": "answer", "run": "r", "scheme": "root", "session": 0, "index": 0, '
            '"first": "a", "second": "b", "answer": "first"}',
            "first segment 'a' is not defined",
        ),
    ],
)
def test_bad_label_files_name_the_line_and_problem(tmp_path, content, message):
    path = tmp_path / "bad.jsonl"
    path.write_text(content)
    with pytest.raises(ValueError, match=message):
        read_label_file(path)


def test_replay_teacher_trains_on_exactly_the_recorded_labels(label_file, tmp_path):
    config = tiny_config(
        teacher=f"replay:{label_file}", steps=2300, reward_batch=8, max_feedback=8
    )  # the file's one session of 8 (tiny_config gives a budget; a larger one is refused)
    trainer = Trainer(config, RunDir.create(tmp_path / "run", config, "cpu"))
    summary = trainer.train()
    labels = read_label_file(label_file)
    names = list(dict.fromkeys(n for a in labels.answers for n in (a["first"], a["second"])))
    local = {n: k for k, n in enumerate(names)}
    expected = augment(
        AnsweredQuestion(
            Question(k, local[a["first"]], local[a["second"]], True), Answer(a["answer"])
        )
        for k, a in enumerate(labels.answers)
    )
    store = trainer.labels
    got = {
        (store.first[i], store.second[i], store.labels[i], store.inferred[i])
        for i in range(len(store))
    }
    assert got == {(p.first, p.second, p.label, p.inferred) for p in expected.pairs}
    assert summary["sessions"] == 1 and summary["asked"] == 8  # the file had one session
    for k, name in enumerate(names):
        assert np.array_equal(
            store.segments[k], np.asarray(labels.segments[name]["features"], np.float32)
        )


def test_replay_teacher_rejects_another_task_and_a_missing_file(label_file, tmp_path, capsys):
    out = tmp_path / "run"
    code = main(
        [
            "train",
            "--task",
            "dmc:walker_walk",
            "--teacher",
            f"replay:{label_file}",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert code == 2
    err = capsys.readouterr().err
    assert "--task dmc:walker_walk conflicts with the replay file's task dmc:cartpole" in err
    code = main(
        ["train", "--teacher", "replay:/nope.jsonl", "--out", str(tmp_path / "r2"), "--quiet"]
    )
    assert code == 2 and "/nope.jsonl does not exist" in capsys.readouterr().err
    assert main(["train", "--teacher", "human", "--out", str(tmp_path / "r3")]) == 2
    assert "seqrank label online" in capsys.readouterr().err


class Answerer(threading.Thread):
    """A scripted person at the page: answers every question by the true return."""

    def __init__(self, client: TestClient, delay: float = 0.0):
        super().__init__(daemon=True)
        self.client, self.delay, self.halt = client, delay, threading.Event()
        self.answered = 0
        self.gate = lambda state: True

    def run(self) -> None:
        while not self.halt.is_set():
            state = self.client.get("/api/state").json()
            if state["status"] != "question" or not self.gate(state):
                time.sleep(0.02)
                continue
            time.sleep(self.delay)
            question = state["question"]
            body = {"question_id": question["id"], "choice": "left", "latency_ms": 10}
            if self.client.post("/api/answer", json=body).status_code == 200:
                self.answered += 1


def train_answered(trainer, hub, answerer: Answerer) -> dict:
    """Train while `answerer` answers on the page; stop both afterwards."""
    answerer.start()
    try:
        return trainer.train()
    finally:
        answerer.halt.set()
        hub.stop.set()


def online_trainer(path, wait: bool, **overrides):
    config = tiny_config(teacher="human", record_states=1, **overrides)
    run = RunDir.create(path, config, "cpu")
    hub = open_hub(path, config.task, ServerOptions(countdown_s=0, size=64))
    trainer = Trainer(
        config, run, source=HumanSource(hub, "online", config.seed), wait_for_feedback=wait
    )
    return trainer, hub


def test_online_training_asks_the_person_and_learns_from_the_answers(tmp_path):
    trainer, hub = online_trainer(tmp_path / "run", wait=True, steps=2300, max_feedback=20)
    answerer = Answerer(page_client(hub))
    summary = train_answered(trainer, hub, answerer)
    assert summary["asked"] == 20 and summary["sessions"] == 2
    stored = hub.db.answered_questions("online")
    assert len(stored) == 20 and [q.session for q, _ in stored] == [0] * 10 + [1] * 10
    asked = [i for i in range(len(trainer.labels)) if not trainer.labels.inferred[i]]
    assert len(asked) == 20
    hub.renderer.close()


def test_no_wait_keeps_training_while_a_session_is_answered(tmp_path):
    trainer, hub = online_trainer(tmp_path / "run", wait=False, steps=2300, max_feedback=20)
    answerer = Answerer(page_client(hub))
    release = threading.Event()  # the person answers the second session only after step 2100
    answerer.gate = lambda state: state["question"]["session"] == 1 or release.is_set()

    def watch(step, live):
        if step >= 2100 and not release.is_set():
            release.set()
            # hold training here until the person has answered, so that the session is sure
            # to be counted before the run ends (however slow the machine)
            if trainer.sessions.pending is not None:
                trainer.sessions.pending[1].result(timeout=120)

    trainer.progress = watch
    summary = train_answered(trainer, hub, answerer)
    assert summary["sessions"] == 2 and summary["asked"] == 20
    sessions = [r for r in trainer.run_dir.read_metrics() if r["kind"] == "feedback"]
    # the second session was asked at step 1700 and counted once answered, after step 2100:
    # the agent trained on the first session's reward in between
    assert sessions[0]["step"] == 1200 and sessions[1]["step"] >= 2100
    hub.renderer.close()


def test_study_report_matches_hand_computed_statistics(tmp_path):
    satisfaction = {"p1": (2, 3, 4), "p2": (3, 3, 5), "p3": (1, 4, 4)}
    reward = {"p1": (100.0, 150.0, 220.0), "p2": (80.0, 120.0, 200.0), "p3": (90.0, 160.0, 150.0)}
    methods = ("pairwise", "sequential", "root")
    for participant in satisfaction:
        directory = tmp_path / participant
        directory.mkdir()
        (directory / "study.json").write_text(json.dumps({"order": list(methods)}))
        db = LabelDB.in_dir(directory)
        for k, method in enumerate(methods):
            db.record_survey(method, method, satisfaction[participant][k], "speed", participant)
            (directory / method).mkdir()
            (directory / method / "summary.json").write_text(
                json.dumps({"final_eval_return": reward[participant][k]})
            )
        db.close()
    assert main(["study-report", str(tmp_path), "--json", str(tmp_path / "r.json")]) == 0
    report = json.loads((tmp_path / "r.json").read_text())
    root = report["methods"]["root"]["satisfaction"]
    assert root["n"] == 3 and root["mean"] == pytest.approx(13 / 3)
    assert root["std"] == pytest.approx(np.std([4, 5, 4], ddof=1))
    test = next(
        t
        for t in report["tests"]
        if (t["metric"], t["a"], t["b"]) == ("reward", "pairwise", "root")
    )
    d = np.array([100 - 220, 80 - 200, 90 - 150])
    t_value = d.mean() / (d.std(ddof=1) / np.sqrt(3))
    assert test["t"] == pytest.approx(t_value) and test["n"] == 3
    # two-sided p from the t distribution with 2 degrees of freedom: 1 - |t| / sqrt(t^2 + 2)
    assert test["p"] == pytest.approx(1 - abs(t_value) / np.sqrt(t_value**2 + 2))
    assert "| root |" in (tmp_path / "study-report.md").read_text()


def test_offline_pool_rolls_out_a_saved_policy(tmp_path):
    from seqrank.labelling.app import OfflineOptions, rollout_episodes

    config = tiny_config(steps=1300, max_feedback=10)
    run = RunDir.create(tmp_path / "run", config, "cpu")
    options = OfflineOptions(config.task, "root", 5, 1, 50, 2, 0, run.path)
    with pytest.raises(ValueError, match="has no checkpoint yet"):
        rollout_episodes(options, lambda text: None)
    Trainer(config, run).train()
    store = rollout_episodes(options, lambda text: None)
    assert len(store) == 2
    for episode in store.episodes:
        assert episode.states is not None and len(episode.states) == len(episode.reward) == 1000
        assert np.abs(episode.action).max() <= 1.0


def test_online_run_stopped_mid_session_resumes_at_the_first_unanswered_question(tmp_path):
    from seqrank.labelling.human import Stopped

    path = tmp_path / "run"
    trainer, hub = online_trainer(path, wait=True, steps=2300, max_feedback=20)
    answerer = Answerer(page_client(hub))
    # the person answers all of session 1 and 4 questions of session 2, then the server stops
    # while the 15th question is on screen

    def gate(state):
        if answerer.answered >= 14:
            hub.stop.set()
            return False
        return True

    answerer.gate = gate
    answerer.start()
    with pytest.raises(Stopped):
        trainer.train()
    answerer.halt.set()
    hub.renderer.close()
    hub.db.close()
    before = LabelDB.in_dir(path)
    first_answers = [(q.id, q.first, q.second, a.choice) for q, a in before.answered_questions()]
    before.close()
    assert len(first_answers) == 14

    run = RunDir.open(path)
    hub = open_hub(path, run.read_config().task, ServerOptions(countdown_s=0, size=64))
    resumed = Trainer(run.read_config(), run, source=HumanSource(hub, "online", 3))
    resumed.load_checkpoint(run.load_checkpoint())
    answerer = Answerer(page_client(hub))
    summary = train_answered(resumed, hub, answerer)
    assert summary["asked"] == 20 and answerer.answered == 6  # only the 6 unanswered
    after = [(q.id, q.first, q.second, a.choice) for q, a in hub.db.answered_questions()]
    assert after[:14] == first_answers
    assert [q.index for q, _ in hub.db.answered_questions()] == list(range(10)) * 2
    hub.renderer.close()


def test_export_refuses_a_file_already_there_and_writes_nothing(label_file, tmp_path, capsys):
    """`labels export -o FILE` writes a new file: one already there is refused in one line
    and left as it was (it was overwritten silently), from a labelling directory and a run."""
    db = LabelDB.in_dir(tmp_path / "labels")
    import_file(db, label_file)
    db.close()
    run = RunDir.create(tmp_path / "run", tiny_config(), "cpu")
    run.release()
    kept = tmp_path / "kept.jsonl"
    kept.write_text("mine\n")
    for source in ("labels", "run"):
        assert main(["labels", "export", str(tmp_path / source), "-o", str(kept)]) == 2
        said = capsys.readouterr().err
        assert said.endswith(
            f"label file {kept} already exists; choose another --output or remove it\n"
        )
        assert said.count("\n") == 1
        assert kept.read_text() == "mine\n"
        assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.jsonl", "labels", "run"]
    fresh = tmp_path / "new.jsonl"
    assert main(["labels", "export", str(tmp_path / "labels"), "-o", str(fresh)]) == 0
    assert len(read_label_file(fresh).answers) == 8


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["label", "offline", "--task", "nope"], "unknown --task 'nope'"),
        (["label", "online", "--countdown", "-1"], "--countdown -1.0"),
        (["label", "online", "--teacher", "oracle"], "the labelling page's teacher is the person"),
        (["label", "study", "--participant", "p", "--methods", "root,foo"], "distinct schemes"),
        (["label", "study", "--participant", "p", "--scheme", "root"], "drop --resume/--out"),
        (["labels", "export", "/nowhere", "-o", "x.jsonl"], "holds no labels.sqlite"),
        (["study-report", "/nowhere"], "holds no participant"),
    ],
)
def test_bad_labelling_commands_name_the_problem_and_create_nothing(
    tmp_path, monkeypatch, capsys, args, message
):
    monkeypatch.chdir(tmp_path)
    out = [] if args[0] != "label" or args[1] != "online" else ["--out", str(tmp_path / "run")]
    assert main([*args, *out]) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--methods", "root,foo"], "distinct schemes"),
        (["--scheme", "root"], "drop --resume/--out"),
    ],
)
def test_a_study_names_its_bad_settings_before_a_busy_port(
    tmp_path, monkeypatch, capsys, args, message
):
    import socket

    monkeypatch.chdir(tmp_path)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = str(busy.getsockname()[1])
        assert main(["label", "study", "--participant", "p", "--port", port, *args]) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_label_file_whose_segments_keep_no_states_or_context_imports(label_file, tmp_path):
    """`states` and `context` are optional in a label file (a file written by hand, or by
    another tool): reading the file accepts it, and so does importing it."""
    bare = tmp_path / "bare.jsonl"
    lines = [json.loads(line) for line in label_file.read_text().splitlines()]
    for line in lines:
        if line["type"] == "segment":
            line.pop("states", None)
            line.pop("context", None)
    bare.write_text("".join(json.dumps(line) + "\n" for line in lines))
    labels = read_label_file(bare)
    segments = labels.session_segments(list(labels.segments))
    assert segments.states == [None] * len(labels.segments)
    assert segments.contexts == [None] * len(labels.segments)
    assert import_file(LabelDB.in_dir(tmp_path / "copy"), bare) == 8
