"""Gold pairs a team agreed on (issue 49): `seqrank labels export --agreed-by N` keeps the
pairs N or more people answered alike, each once, and the file serves a later run's
`--gold`; an export that could hold no pair, or of a run directory, is refused in one line
and writes nothing."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path
from threading import Event

import numpy as np
import pytest

from seqrank.cli import main
from seqrank.episodes import Segments
from seqrank.labelling.gold import read_gold
from support.crowd import answering, bare_team, team_request
from support.pages import TASK

TEAM = ["alice", "bob", "carol"]


def _lower_first(question) -> str:
    """Prefers the segment stored first, whichever side it is shown on."""
    return "left" if question.left == min(question.first, question.second) else "right"


def _carol(question) -> str:
    """carol agrees with the others except on pairs whose lower segment id is divisible by 3."""
    agreed = _lower_first(question)
    if min(question.first, question.second) % 3:
        return agreed
    return "right" if agreed == "left" else "left"


def _team_directory(tmp_path: Path, states: bool = True) -> Path:
    """A team's labelling directory: one sequential session of 12 questions, each asked of
    all three (overlap until 1000), over segments that keep physics states (or not)."""
    directory = tmp_path / "team"
    hub = bare_team(directory, TEAM, 60.0, overlap=0.0, overlap_until=1000)
    for key, value in {"task": TASK, "obs_dim": 4, "act_dim": 1, "segment_length": 3}.items():
        hub.db.set_meta(key, json.dumps(value))
    request = team_request("sequential", 12, 3, spare=2)
    n = len(request.segments.rewards)
    states = [np.full((3, 5), float(k)) if states else None for k in range(n)]
    pool = Segments(request.segments.features, request.segments.rewards, states, [None] * n)
    done = Event()
    rules = {"alice": _lower_first, "bob": _lower_first, "carol": _carol}
    people = [answering(hub, name, rules[name], done) for name in TEAM]
    from dataclasses import replace

    hub.source("offline", 3).ask_session(replace(request, segments=pool))
    done.set()
    for person in people:
        person.join(10)
    hub.db.close()
    return directory


def _file(path: Path) -> tuple[dict, list[dict]]:
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    return lines[0], [line for line in lines if line["type"] == "answer"]


def _alike(answers: list[dict], people: int) -> set[frozenset[str]]:
    """From a full export: the pairs `people` or more answered, all for the same segment."""
    preferred, authors = defaultdict(set), defaultdict(set)
    for answer in answers:
        pair = frozenset((answer["first"], answer["second"]))
        said = {"first": answer["first"], "second": answer["second"]}.get(answer["answer"])
        preferred[pair].add(said)
        authors[pair].add(answer["annotator"])
    return {
        pair
        for pair in preferred
        if len(authors[pair]) >= people
        and len(preferred[pair]) == 1
        and None not in preferred[pair]
    }


def test_the_agreed_pairs_are_those_answered_alike_each_once(tmp_path, capsys):
    directory = _team_directory(tmp_path)
    assert main(["labels", "export", str(directory), "-o", str(tmp_path / "all.jsonl")]) == 0
    _, every = _file(tmp_path / "all.jsonl")
    assert len({frozenset((a["first"], a["second"])) for a in every}) == 12
    for people in (2, 3):
        out = tmp_path / f"agreed-{people}.jsonl"
        assert (
            main(["labels", "export", str(directory), "-o", str(out), "--agreed-by", str(people)])
            == 0
        )
        header, kept = _file(out)
        pairs = [frozenset((a["first"], a["second"])) for a in kept]
        assert len(pairs) == len(set(pairs))  # each pair once
        assert set(pairs) == _alike(every, people)
        assert 0 < len(pairs) < 12  # carol's dissent leaves some out
        assert header["task"] == TASK
        assert f"{len(kept)} answers" in capsys.readouterr().out
    gold = read_gold(tmp_path / "agreed-3.jsonl", TASK, 3)  # a later run's gold file
    assert len(gold.pairs) == len(_file(tmp_path / "agreed-3.jsonl")[1])


def test_an_export_that_could_hold_no_agreed_pair_is_refused(tmp_path, capsys):
    directory = _team_directory(tmp_path)
    out = tmp_path / "gold.jsonl"
    assert main(["labels", "export", str(directory), "-o", str(out), "--agreed-by", "4"]) == 2
    message = capsys.readouterr().err
    assert "no pair of" in message and "4 or more people" in message and not out.exists()
    assert main(["labels", "export", str(directory), "-o", str(out), "--agreed-by", "1"]) == 2
    assert "--agreed-by" in capsys.readouterr().err and not out.exists()


def test_a_run_directory_has_no_agreed_pairs(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.json").write_text("{}")
    out = tmp_path / "gold.jsonl"
    code = main(["labels", "export", str(run), "-o", str(out), "--agreed-by", "2"])
    assert code == 2 and "run directory" in capsys.readouterr().err and not out.exists()


@pytest.fixture(autouse=True)
def _quiet(monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # one-line refusals stay on one line


def test_a_teams_exports_import_into_a_new_directory_and_come_back_the_same(tmp_path, capsys):
    """A team's export leaves out the spare segments of a pool, and an agreed one most of
    its pairs: their pool ids have gaps, which an import keeps."""
    directory = _team_directory(tmp_path)
    for name, extra in (("all", []), ("agreed", ["--agreed-by", "3"])):
        exported = tmp_path / f"{name}.jsonl"
        assert main(["labels", "export", str(directory), "-o", str(exported), *extra]) == 0
        into = tmp_path / f"into-{name}"
        assert main(["labels", "import", str(exported), str(into)]) == 0
        again = tmp_path / f"again-{name}.jsonl"
        assert main(["labels", "export", str(into), "-o", str(again)]) == 0
        said = [(a["first"], a["second"], a["answer"], a["annotator"]) for a in _file(exported)[1]]
        back = [(a["first"], a["second"], a["answer"], a["annotator"]) for a in _file(again)[1]]
        assert sorted(back) == sorted(said) and said


def test_an_agreed_file_that_cannot_serve_as_gold_says_so(tmp_path, capsys):
    directory = _team_directory(tmp_path, states=False)
    out = tmp_path / "agreed.jsonl"
    assert main(["labels", "export", str(directory), "-o", str(out), "--agreed-by", "3"]) == 0
    assert "cannot serve as --gold" in capsys.readouterr().out
    with pytest.raises(ValueError, match="keep their states"):
        read_gold(out, TASK, 3)
    kept = tmp_path / "kept.jsonl"
    assert (
        main(
            [
                "labels",
                "export",
                str(_team_directory(tmp_path / "b")),
                "-o",
                str(kept),
                "--agreed-by",
                "3",
            ]
        )
        == 0
    )
    assert "cannot serve" not in capsys.readouterr().out
