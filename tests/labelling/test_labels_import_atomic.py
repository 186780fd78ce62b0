"""`seqrank labels import` is one transaction: a record that fails once its session's row,
pool and first answers are written leaves the store exactly as it was (a half-made session
looked imported, so a second try added nothing to it), and says what failed in one line."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import pytest

from seqrank.cli import main
from seqrank.labelling.db import DB_NAME, LabelDB
from seqrank.labelling.jsonl import export_file
from support.pages import Page


@pytest.fixture(scope="module")
def label_file(tmp_path_factory) -> Path:
    """An offline session of 8 questions, answered and exported."""
    directory = tmp_path_factory.mktemp("offline")
    page = Page(directory / "labels", "sequential", 8)
    try:
        for choice in ["left", "right", "equal", "left", "skip", "right", "left", "right"]:
            page.answer(choice)
        page.done.wait(10)
        path = directory / "labels.jsonl"
        export_file(page.hub.db, path)
    finally:
        page.close()
    return path


def _as_run(source: Path, target: Path, run: str, slow_at: int | None = None) -> Path:
    """The file's answers under another run; `slow_at`: that answer's latency not a number
    (the file reader lets it through, the importer fails on it after storing the session)."""
    records = [json.loads(line) for line in source.read_text().splitlines()]
    answers = [r for r in records if r["type"] == "answer"]
    for record in answers:
        record["run"] = run
    if slow_at is not None:
        answers[slow_at]["latency_ms"] = "slow"
    target.write_text("".join(json.dumps(r) + "\n" for r in records))
    return target


def _dump(path: Path) -> list[str]:
    conn = sqlite3.connect(path)
    try:
        return list(conn.iterdump())
    finally:
        conn.close()


def _failing_write(monkeypatch) -> None:
    """The third answer's write fails (a disk error, say)."""
    record_answer, calls = LabelDB.record_answer, []

    def failing(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise sqlite3.OperationalError("disk I/O error")
        return record_answer(self, *args, **kwargs)

    monkeypatch.setattr(LabelDB, "record_answer", failing)


@pytest.mark.parametrize(
    ("failure", "message"),
    [
        ("record", "question 7: could not convert string to float: 'slow'; nothing imported"),
        ("write", "question 2: disk I/O error; nothing imported"),
    ],
)
def test_an_import_failing_part_way_leaves_the_store_as_it_was(
    label_file, tmp_path, monkeypatch, capsys, failure, message
):
    directory = tmp_path / "labels"
    assert main(["labels", "import", str(label_file), str(directory)]) == 0
    before = _dump(directory / DB_NAME)
    capsys.readouterr()
    slow_at = 7 if failure == "record" else None
    bad = _as_run(label_file, tmp_path / "bad.jsonl", "again", slow_at)
    with monkeypatch.context() as patched:
        if failure == "write":
            _failing_write(patched)
        assert main(["labels", "import", str(bad), str(directory)]) == 2
    assert _dump(directory / DB_NAME) == before
    said = capsys.readouterr().err
    assert said.count("\n") == 1
    assert said.startswith(f"seqrank labels: error: {bad}: run 'again' session 0 {message}")
    good = _as_run(label_file, tmp_path / "good.jsonl", "again")
    assert main(["labels", "import", str(good), str(directory)]) == 0
    assert "8 answers added" in capsys.readouterr().out
