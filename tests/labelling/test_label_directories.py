"""A labelling directory: one `seqrank label` at a time (a killed one's lock is taken over),
Ctrl-C writes the export of every answer, and a rerun with other settings is refused with
one line naming them."""

from __future__ import annotations

import signal
import time

import httpx
import pytest

from seqrank.cli import main
from seqrank.labelling.db import LabelDB
from support.pages import start_command

COMMAND = [
    "label", "offline", "--task", "dmc:cartpole_swingup", "--scheme", "root",
    "--questions", "3", "--episodes", "1", "--countdown", "0", "--port", "0",
]  # fmt: skip


def answer_one(url: str) -> None:
    for _ in range(1200):
        state = httpx.get(f"{url}/api/state").json()
        if state["status"] == "question":
            body = {"question_id": state["question"]["id"], "choice": "left", "latency_ms": 9}
            assert httpx.post(f"{url}/api/answer", json=body).status_code == 200
            return
        time.sleep(0.05)
    raise AssertionError("no question was shown")


def test_one_label_process_per_directory_ctrl_c_exports_and_changed_settings_are_named(
    tmp_path, capsys
):
    directory = tmp_path / "labels"
    command = [*COMMAND, "--out", str(directory)]
    process, url = start_command(command)
    try:
        answer_one(url)
        # a second labelling process on the same directory is refused
        assert main(command) == 2
        err = capsys.readouterr().err
        assert f"labelling directory {directory} is in use by another seqrank process" in err
        assert f"(pid {process.pid})" in err and len(err.strip().splitlines()) == 1
        # Ctrl-C: the page stops waiting and the export holds the answer given
        process.send_signal(signal.SIGINT)
        assert process.wait(60) == 128 + signal.SIGINT
    finally:
        if process.poll() is None:
            process.kill()
    exported = (directory / "labels.jsonl").read_text()
    assert exported.count('"type": "answer"') == 1
    assert len(LabelDB.in_dir(directory).answered_questions()) == 1

    # a process killed outright leaves its lock to the next one, which refuses other settings
    process, url = start_command(command)
    process.send_signal(signal.SIGKILL)
    process.wait(10)
    changed = [*COMMAND, "--out", str(directory)]
    changed[changed.index("root")] = "sequential"
    changed[changed.index("--questions") + 1] = "4"
    assert main(changed) == 2
    err = capsys.readouterr().err
    assert (
        f"labelling directory {directory} was started with --questions 3 (not 4), --scheme "
        "root (not sequential); rerun with its settings to continue, or choose another --out"
    ) in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_a_study_rerun_with_other_settings_is_refused_before_the_page_starts(tmp_path, capsys):
    from seqrank.training.runs import RunDir
    from support.runs import tiny_config

    begun = tiny_config(scheme="root", teacher="human", record_states=1)
    RunDir.create(tmp_path / "study" / "p1" / "root", begun, "cpu").release()
    args = ["label", "study", "--participant", "p1", "--study-dir", str(tmp_path / "study")]
    settings = [f"--{k.replace('_', '-')}={v}" for k, v in begun.as_dict().items()]
    kept = [s for s in settings if s.split("=")[0] not in ("--scheme", "--teacher", "--scale")]
    assert main([*args, "--methods", "root", "--port", "0", *kept, "--max-feedback=20"]) == 2
    err = capsys.readouterr().err
    assert "participant p1 began method root with other settings (max_feedback 30 -> 20)" in err
    assert len(err.strip().splitlines()) == 1


def test_a_rerun_that_changes_a_continuable_setting_is_told_so(tmp_path):
    from seqrank.labelling.directory import check_offline_settings, record_offline_settings

    began = {"scheme": "root", "questions": 3, "annotators": ["a", "b"], "overlap": 0.1}
    db = LabelDB.in_dir(tmp_path)
    record_offline_settings(db, {**began, "overlap_until": 50})
    db.close()
    same = check_offline_settings(tmp_path, {**began, "overlap_until": 50})
    changed = check_offline_settings(
        tmp_path, {**began, "annotators": ["a", "b", "c"], "overlap_until": 10}
    )
    assert same == []
    assert changed == ["--annotators a,b,c (was a,b)", "--overlap-until 10 (was 50)"]


def _gold_file(path, shift: float):
    """A label file of cartpole's 3-step segments whose clips could be shown (they keep
    physics states); `shift` moves every feature, so two shifts give other gold pairs."""
    import json

    from support.labels import write_labels

    write_labels(path, "pairwise", (2,), 3)
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    for line in lines:
        if line["type"] == "segment":
            line["features"] = [[x + shift for x in step] for step in line["features"]]
            line["states"] = [[0.0] * 5] * 3
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def test_a_directory_of_other_labels_is_refused_before_a_progress_line(
    tmp_path, monkeypatch, capsys
):
    """Labels of another task (in a directory that keeps no offline settings: `label
    online` labelled in it) and a rerun given other gold pairs are refused in one line,
    before the page's address or a "continuing" line is said, and nothing is written."""
    import json

    from seqrank.labelling import app

    online = tmp_path / "online"
    db = LabelDB.in_dir(online)
    app.record_task(db, "dmc:walker_walk", 24, 6, 50)
    db.close()
    before = {p.name: p.stat().st_mtime_ns for p in online.iterdir()}
    assert main([*COMMAND, "--out", str(online)]) == 2
    err = capsys.readouterr().err
    refusal = f"labelling directory {online} holds labels of task dmc:walker_walk, not "
    assert err.startswith(f"seqrank label: error: {refusal}dmc:cartpole_swingup: choose another")
    assert len(err.strip().splitlines()) == 1
    after = {p.name: p.stat().st_mtime_ns for p in online.iterdir() if p.name != ".lock"}
    assert after == before  # the lock taken to read it aside (`seqrank.dirs`)
    db = LabelDB.in_dir(online)
    assert db.get_meta("offline_settings") is None and db.sessions() == []
    db.close()

    monkeypatch.setattr(app, "run_offline", lambda *args: 0)  # no questions: the gold kept
    team = [*COMMAND, "--segment-length", "3", "--annotators", "a,b", "--out", str(tmp_path / "t")]
    assert main([*team, "--gold", str(_gold_file(tmp_path / "g1.jsonl", 0.0))]) == 0
    capsys.readouterr()
    other = _gold_file(tmp_path / "g2.jsonl", 1.0)
    assert main([*team, "--gold", str(other), "--sessions", "2"]) == 2
    err = capsys.readouterr().err
    assert "this labelling directory was started with the gold pairs of" in err
    assert len(err.strip().splitlines()) == 1, err  # not "continuing ... --sessions 2 (was 1)"
    settings = LabelDB.in_dir(tmp_path / "t").get_meta("offline_settings")
    assert json.loads(settings or "{}")["sessions"] == 1


def test_a_task_is_the_same_task_however_it_is_spelled(tmp_path):
    from seqrank.envs import same_task
    from seqrank.labelling.app import record_task
    from seqrank.labelling.directory import check_offline_settings, record_offline_settings

    assert same_task("walker_walk", "dmc:walker_walk")
    assert same_task("window-open", "metaworld:window-open-v3")
    assert not same_task("walker_walk", "dmc:walker_run")
    assert not same_task("nonsense", "dmc:nonsense") and same_task("nonsense", "nonsense")
    began = {"task": "walker_walk", "scheme": "root", "segment_length": 50}
    db = LabelDB.in_dir(tmp_path)
    record_offline_settings(db, began)
    record_task(db, "walker_walk", 24, 6, 50)
    record_task(db, "dmc:walker_walk", 24, 6, 50)  # a rerun naming it otherwise continues
    db.close()
    assert check_offline_settings(tmp_path, {**began, "task": "dmc:walker_walk"}) == []
    with pytest.raises(ValueError, match="--task walker_walk"):
        check_offline_settings(tmp_path, {**began, "task": "dmc:walker_run"})
