"""A team's names (issue 45, item 13): ASCII letters, digits, '-', '_' and '.', starting
with a letter, at most 40 characters, unique whatever their case, and not `operator`. A
name that looks like another (`аlice` with a Cyrillic а) is refused by `seqrank label`
in one line that shows the name as the escape it is, exit 2, nothing made."""

from __future__ import annotations

from pathlib import Path

import pytest

from seqrank.cli import main

ONLINE = ["label", "online", "--device", "cpu", "--port", "0", "--out", "online-run", "--dry-run"]
OFFLINE = ["label", "offline", "--task", "dmc:cartpole_swingup", "--port", "0", "--out", "labels"]
RULE = "use ASCII letters, digits, '-', '_' and '.', starting with a letter, at most 40"
CASES = [
    ("\u0430lice,bob", "'\\u0430lice' is not a name: '\\u0430' (CYRILLIC SMALL LETTER A)"),
    ("alice,\uff42ob", "'\\uff42ob' is not a name: '\\uff42' (FULLWIDTH LATIN SMALL LETTER B)"),
    ("\xe9ve,bob", "'\\xe9ve' is not a name: '\\xe9' (LATIN SMALL LETTER E WITH ACUTE)"),
    ("alice\u200b,bob", "'alice\\u200b' is not a name: '\\u200b' (ZERO WIDTH SPACE)"),
    ("alice,2bob", f"'2bob' is not a name; {RULE}"),
    ("alice,b/ob", "'b/ob' is not a name: '/' (SOLIDUS) is not accepted"),
    (f"alice,{'b' * 41}", f"is not a name; {RULE}"),
    ("alice,operator", "'operator' is reserved for the operator's page"),
    ("Operator,bob", "'Operator' is reserved for the operator's page"),
    ("Alice,bob,alice", "alice given twice (as Alice: case is not told apart); names are unique"),
]


def page_opened(*args, **kwargs):
    raise AssertionError("the names were taken: the page opened")


@pytest.mark.parametrize("command", [ONLINE, OFFLINE], ids=["online", "offline"])
@pytest.mark.parametrize(("names", "message"), CASES, ids=[ascii(n) for n, _ in CASES])
def test_a_bad_annotator_name_is_refused_in_one_line_and_nothing_is_made(
    command, names, message, tmp_path, monkeypatch, capsys
):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    monkeypatch.setattr("seqrank.labelling.app.open_hub", page_opened)  # never wait for people
    code = main([*command, "--annotators", names])
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"--annotators {names!a}: " in err and message in err
    assert len(err.strip().splitlines()) == 1 and err.isascii() and "Traceback" not in err
    if "is not a name" in message:
        assert RULE in err  # the accepted set is named
    assert list(work.iterdir()) == []  # nothing made


def test_names_of_the_accepted_set_are_taken(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    names = "alice,Bob-2,carol.d,dan_e"
    assert main([*ONLINE, "--annotators", names]) == 0, capsys.readouterr().err
    assert not Path("online-run").exists()
