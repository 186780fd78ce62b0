"""Gold pairs at a team's page (issue 49): a label file's trusted answers shown to each
member among their questions, unannounced; they spend no budget, train nothing, are not
exported, come back the same after a replay, and count against whoever contradicts them
on the operator page. A gold file that cannot serve the run is refused in one line."""

from __future__ import annotations

import json
from pathlib import Path
from threading import Event

import numpy as np
import pytest

from seqrank.feedback.labels import LabelStore
from seqrank.feedback.session import store_session
from seqrank.labelling import crowd_source
from seqrank.labelling.crowd_keys import GOLD_CHECKS, GOLD_RUN
from seqrank.labelling.crowd_report import operator_view
from seqrank.labelling.crowd_team import open_team
from seqrank.labelling.db import LabelDB
from seqrank.labelling.gold import GOLD_META, read_gold
from seqrank.labelling.human import Hub, PageSettings
from support.crowd import answering, team_request
from support.pages import TASK

TEAM = ["alice", "bob", "carol"]
PAIRS = 6  # gold pairs: segment 2k against 2k + 1, 2k preferred when k is even


def gold_file(path: Path, task: str = TASK, length: int = 3, states: bool = True) -> Path:
    header = {"type": "header", "format": "seqrank-labels", "version": 1, "task": task,
              "obs_dim": 2, "act_dim": 1, "segment_length": length}  # fmt: skip
    lines = [header]
    for k in range(2 * PAIRS):
        segment = {"type": "segment", "id": f"offline/0/{k}", "run": "offline", "session": 0}
        segment["features"] = [[float(k), 0.0, 1.0]] * length
        segment["rewards"] = [0.1 * k] * length
        segment["states"] = [[float(k)] * 4] * length if states else None
        lines.append({**segment, "context": None})
    for k in range(PAIRS):  # the higher-numbered segment preferred when k is odd
        answer = {"type": "answer", "run": "offline", "scheme": "pairwise", "session": 0}
        a, b = f"offline/0/{2 * k}", f"offline/0/{2 * k + 1}"
        listed = (a, b) if k % 3 else (b, a)  # some pairs asked the other way round
        said = "first" if (listed[0] == a) == (k % 2 == 0) else "second"
        lines.append(
            {**answer, "index": k, "first": listed[0], "second": listed[1], "answer": said}
        )
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def _member(hub: Hub, honest: bool):
    """A member who answers chain questions by a fixed rule and gold questions by their
    known order (`honest`) or against it."""
    better = {(a, b): a if first else b for a, b, first in hub.crowd.gold}

    def choose(question) -> str:
        if question.run != GOLD_RUN:
            return ("left", "right")[(question.left * 7 + question.right) % 2]
        right_side = "left" if question.left == better[question.first, question.second] else "right"
        return right_side if honest else ("right" if right_side == "left" else "left")

    return choose


def _team(directory: Path, names: list[str]) -> Hub:
    hub = Hub(LabelDB.in_dir(directory / "team"), PageSettings(0.0, "tester", None))
    gold = read_gold(gold_file(directory / "gold.jsonl"), TASK, 3)
    open_team(hub, names, 0.0, 60.0, 0, gold)
    return hub


@pytest.fixture
def team_with_gold(tmp_path, monkeypatch):
    monkeypatch.setattr(crowd_source, "GOLD_SHARE", 0.5)  # many gold questions in few answers
    hub = _team(tmp_path, TEAM)
    yield hub
    hub.db.close()


def _session(hub: Hub, seed: int = 3):
    done, names = Event(), hub.crowd.annotators
    choose = {name: _member(hub, honest=name != "carol") for name in names}
    people = [answering(hub, name, choose[name], done) for name in names]
    request = team_request("pairwise", 30, len(names), spare=2)
    pool, record = hub.source("offline", seed).ask_session(request)
    done.set()
    for person in people:
        person.join(10)
    return pool, record


def test_gold_questions_reach_every_member_and_find_the_one_who_contradicts_them(team_with_gold):
    hub = team_with_gold
    _, record = _session(hub)
    assert len(record.answers) == 30  # the budget: gold questions are not among them
    view = operator_view(hub, "http://127.0.0.1/")
    people = {p["name"]: p for p in view["annotators"]}
    assert all(people[name]["gold_answered"] > 0 for name in TEAM)
    assert people["alice"]["gold_right"] == people["alice"]["gold_answered"]
    assert people["carol"]["gold_right"] == 0
    assert people["carol"]["reliability"] < people["alice"]["reliability"]
    assert all(q.run != GOLD_RUN for q, _ in hub.db.answered_questions())  # not exported


def test_between_two_people_the_gold_answer_says_which_of_them_is_wrong(tmp_path, monkeypatch):
    """alice and carol disagree on every gold pair they both answered: without the known
    order the two would look alike; with it carol is found out, on the operator page and
    in the estimate reward training acts on."""
    monkeypatch.setattr(crowd_source, "GOLD_SHARE", 0.5)
    hub = _team(tmp_path, ["alice", "carol"])
    pool, record = _session(hub)
    people = {p["name"]: p for p in operator_view(hub, "http://127.0.0.1/")["annotators"]}
    assert people["carol"]["gold_answered"] > 0 and people["alice"]["gold_answered"] > 0
    assert people["carol"]["reliability"] < 0.5 < people["alice"]["reliability"]

    gold = record.crowd.gold
    assert {g.annotator for g in gold} == {"alice", "carol"}
    assert all((g.said == g.known) == (g.annotator == "alice") for g in gold)
    labels = LabelStore("drop")
    store_session(pool, record, labels, team_request("pairwise", 30, 2, spare=2))
    trained = labels.reliability()
    assert trained["carol"].estimate < 0.5 < trained["alice"].estimate
    assert len(labels) == 30  # the budget's answers: gold trains nothing
    hub.db.close()


def test_a_replayed_session_gives_the_same_gold_questions_and_no_more(team_with_gold):
    hub = team_with_gold
    _session(hub)
    posed = f"SELECT question_id, annotator FROM crowd_questions WHERE chain = {GOLD_CHECKS}"
    before = sorted(tuple(row) for row in hub.db.rows(posed))
    assert before
    hub.source("offline", 3).ask_session(team_request("pairwise", 30, 3, spare=2))
    assert sorted(tuple(row) for row in hub.db.rows(posed)) == before


def test_a_member_is_shown_each_gold_pair_once_before_any_again(team_with_gold):
    hub = team_with_gold
    _session(hub)
    shown = hub.db.rows(
        "SELECT c.annotator, q.first, q.second FROM crowd_questions c "
        f"JOIN questions q ON q.id = c.question_id WHERE c.chain = {GOLD_CHECKS}"
    )
    for name in TEAM:
        pairs = [(r["first"], r["second"]) for r in shown if r["annotator"] == name]
        assert len(set(pairs[:PAIRS])) == len(pairs[:PAIRS]), name


def test_the_known_order_is_the_files_whichever_way_round_a_pair_was_asked(tmp_path):
    gold = read_gold(gold_file(tmp_path / "gold.jsonl"), TASK, 3)
    assert len(gold.pairs) == PAIRS
    for a, b, first in gold.pairs:
        preferred = gold.segments.features[a if first else b][0][0]  # its number in the file
        other = gold.segments.features[b if first else a][0][0]
        k = int(min(preferred, other)) // 2
        assert preferred == (2 * k if k % 2 == 0 else 2 * k + 1), (a, b, first)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"task": "dmc:walker_walk"}, "is of task 'dmc:walker_walk'; this run's is"),
        ({"length": 30}, "holds segments of 30 steps; this run asks about 3"),
        ({"states": False}, "keeps no physics states, so its clip cannot be shown"),
    ],
)
def test_a_gold_file_that_cannot_serve_the_run_is_refused(tmp_path, change, message):
    path = gold_file(tmp_path / "gold.jsonl", **change)
    with pytest.raises(ValueError, match=message):
        read_gold(path, TASK, 3)


def test_a_gold_file_without_a_known_order_is_refused(tmp_path):
    path = gold_file(tmp_path / "gold.jsonl")
    lines = path.read_text().splitlines()
    both_ways = json.loads(lines[-1])
    both_ways["answer"] = "first" if both_ways["answer"] == "second" else "second"
    path.write_text("\n".join([*lines, json.dumps(both_ways)]) + "\n")
    with pytest.raises(ValueError, match="is answered both ways"):
        read_gold(path, TASK, 3)
    equal = [json.loads(line) for line in lines]
    for line in equal:
        if line["type"] == "answer":
            line["answer"] = "equal"
    path.write_text("".join(json.dumps(line) + "\n" for line in equal))
    with pytest.raises(ValueError, match="holds no 'first' or 'second' answer"):
        read_gold(path, TASK, 3)
    with pytest.raises(ValueError, match="does not exist"):
        read_gold(tmp_path / "missing.jsonl", TASK, 3)


@pytest.mark.parametrize("differ", ["answers", "segments"])
def test_a_directory_started_with_other_gold_refuses_and_keeps_its_own(tmp_path, differ):
    hub = Hub(LabelDB.in_dir(tmp_path / "team"), PageSettings(0.0, "tester", None))
    open_team(hub, TEAM, 0.0, 60.0, 0, read_gold(gold_file(tmp_path / "a.jsonl"), TASK, 3))
    kept, pool = hub.db.get_meta(GOLD_META), hub.db.pool(GOLD_RUN, 0).features
    hub.db.close()
    other = gold_file(tmp_path / "b.jsonl")
    text = other.read_text()
    if differ == "answers":
        other.write_text(text.replace('"answer": "first"', '"answer": "second"'))
    else:
        other.write_text(text.replace("[[0.0, 0.0, 1.0]", "[[0.5, 0.0, 1.0]"))
    again = Hub(LabelDB.in_dir(tmp_path / "team"), PageSettings(0.0, "tester", None))
    with pytest.raises(ValueError, match=r"started with the gold pairs of .*a\.jsonl, not"):
        open_team(again, TEAM, 0.0, 60.0, 0, read_gold(other, TASK, 3))
    assert again.db.get_meta(GOLD_META) == kept
    assert np.array_equal(again.db.pool(GOLD_RUN, 0).features, pool)
    again.db.close()


def test_a_rerun_without_the_gold_file_keeps_asking_the_directorys_gold(tmp_path):
    hub = Hub(LabelDB.in_dir(tmp_path / "team"), PageSettings(0.0, "tester", None))
    open_team(hub, TEAM, 0.0, 60.0, 0, read_gold(gold_file(tmp_path / "a.jsonl"), TASK, 3))
    first = hub.crowd.gold
    hub.db.close()
    again = Hub(LabelDB.in_dir(tmp_path / "team"), PageSettings(0.0, "tester", None))
    open_team(again, TEAM, 0.0, 60.0, 0, None)
    assert again.crowd.gold == first and len(first) == PAIRS
    again.db.close()


def test_a_dry_run_says_which_gold_pairs_the_team_would_be_shown(tmp_path, capsys):
    from seqrank.cli import main

    gold = gold_file(tmp_path / "gold.jsonl")
    argv = ["label", "online", "--device", "cpu", "--port", "0", "--dry-run", "--task", TASK,
            "--segment-length", "3", "--annotators", ",".join(TEAM), "--gold", str(gold),
            "--out", str(tmp_path / "run")]  # fmt: skip
    assert main(argv) == 0
    said = " ".join(capsys.readouterr().err.split())  # (the console wraps long lines)
    assert f"gold: {PAIRS} pairs from {gold.resolve()}" in said
    assert not (tmp_path / "run").exists()
