"""`--crowd-weighting reask` at a team's page (issue 49, item 3): each question a member
flagged before the session answered (a skip too) is asked again of somebody not flagged,
and the record marks those answers as re-asks; nobody else's answers are asked again."""

from __future__ import annotations

from dataclasses import replace
from threading import Event

from seqrank.labelling.crowd_keys import SECOND_OPINIONS
from support.crowd import answering, bare_team, team_request

TEAM = ["ann", "bob", "carol"]


def _choice(question) -> str:
    return ("left", "right", "skip")[(question.left * 7 + question.right) % 3]


def _session(tmp_path, distrusted: frozenset[str], until: int = 0):
    hub = bare_team(tmp_path, TEAM, 60.0, overlap=0.0, overlap_until=until)
    done = Event()
    people = [answering(hub, name, _choice, done) for name in TEAM]
    request = replace(team_request("sequential", 12, 3, spare=2), distrusted=distrusted)
    _, record = hub.source("offline", 3).ask_session(request)
    done.set()
    for person in people:
        person.join(10)
    return hub, record


def test_a_flagged_members_questions_are_asked_again_of_the_others(tmp_path):
    hub, record = _session(tmp_path, frozenset({"carol"}))
    crowd = record.crowd
    carols = [a for a, who in zip(record.answers, crowd.answered_by, strict=True) if who == "carol"]
    assert carols
    reasks = [o for o in crowd.second_opinions if o.reask]
    assert len(reasks) == len(carols) == len(crowd.second_opinions)  # hers, each once
    assert {(o.answered.first, o.answered.second) for o in reasks} == {
        (a.first, a.second) for a in carols
    }
    assert all(o.annotator in ("ann", "bob") for o in reasks)
    excluded = hub.db.rows(f"SELECT excluded FROM crowd_questions WHERE chain = {SECOND_OPINIONS}")
    assert {row["excluded"] for row in excluded} == {"carol"}
    hub.db.close()


def test_nobody_is_asked_again_when_everybody_or_nobody_is_flagged(tmp_path):
    for k, distrusted in enumerate([frozenset(), frozenset(TEAM)]):
        hub, record = _session(tmp_path / str(k), distrusted)
        assert record.crowd is not None and record.crowd.second_opinions == ()
        hub.db.close()


def test_with_two_flagged_only_the_trusted_member_answers_again(tmp_path):
    hub, record = _session(tmp_path, frozenset({"bob", "carol"}))
    reasks = [o for o in record.crowd.second_opinions if o.reask]
    owners = {"bob", "carol"} & set(record.crowd.answered_by)
    assert owners and reasks and {o.annotator for o in reasks} == {"ann"}
    hub.db.close()


def test_a_stored_reask_index_is_never_an_overlap_opinions():
    """A re-ask is told apart from the overlap's opinions by its stored index alone."""
    from seqrank.feedback.overlap import CHECKERS
    from seqrank.labelling.crowd_keys import REASK_NTH

    assert REASK_NTH >= CHECKERS


def test_while_evidence_is_short_a_flagged_answer_is_reasked_of_both_others(tmp_path):
    """As the simulated crowd (`reasks_wanted`): as many re-asks as the overlap would ask
    (two while the author's shared answers are short), in place of its opinions."""
    hub, record = _session(tmp_path, frozenset({"carol"}), until=1000)
    crowd = record.crowd
    carols = [a for a, who in zip(record.answers, crowd.answered_by, strict=True) if who == "carol"]
    reasks = [o for o in crowd.second_opinions if o.reask]
    assert carols and len(reasks) == 2 * len(carols)
    for answer in carols:
        on_it = [
            o
            for o in reasks
            if (o.answered.first, o.answered.second) == (answer.first, answer.second)
        ]
        assert sorted(o.annotator for o in on_it) == ["ann", "bob"]
    theirs = {(a.first, a.second) for a in carols}
    others = [o for o in crowd.second_opinions if not o.reask]
    assert others and all((o.answered.first, o.answered.second) not in theirs for o in others)
    hub.db.close()
