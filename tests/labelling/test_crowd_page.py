"""A team at the labelling page: answers shared out over HTTP, chains kept to one person,
second opinions of another, hand-overs, tokens that cannot act for another, the operator
page."""

from __future__ import annotations

from collections import defaultdict

import pytest

from seqrank.labelling.crowd_keys import ChainStep, key_of
from support.crowd import Annotator, TeamPage, run_team, start_team

TEAM = ["alice", "bob", "carol"]


def chain_answers(page: TeamPage):
    """(session, chain, author, first, second) of every chain answer, and the second
    opinions as (session, index of the question they repeat, author)."""
    tables = page.hub.crowd.tables
    chains, seconds = [], []
    for question, who, chain, _, _ in tables.answered_by():
        if chain >= 0:
            chains.append(
                (question.session, chain, who, question.first, question.second, question.index)
            )
        else:
            seconds.append((question.session, -question.index - 1, who))
    return chains, seconds


@pytest.mark.parametrize("scheme", ["sequential", "root", "pairwise", "ranked"])
def test_three_annotators_at_once_lose_no_answer_and_never_mix_a_chain(tmp_path, scheme):
    page = TeamPage(tmp_path / "labels", TEAM, scheme, questions=12, sessions=2, overlap=0.5)
    try:
        annotators = [Annotator(page, name) for name in TEAM]
        run_team(page, annotators)
        chains, seconds = chain_answers(page)
        tables = page.hub.crowd.tables
        # every chain question answered once: no answer lost or doubled
        assert len(chains) == len({(s, i) for s, _, _, _, _, i in chains})
        for session in (0, 1):
            assert sum(s == session for s, *_ in chains) == 12
            owners = {c.chain: c.owner for c in tables.chains("offline", session)}
            segments_of = defaultdict(set)
            for s, chain, who, first, second, _ in chains:
                if s == session:
                    assert who == owners[chain]  # a chain's answers are its owner's
                    segments_of[who] |= {first, second}
            # everybody worked, and no segment is in two people's chains
            assert set(segments_of) == set(TEAM)
            people = list(segments_of.values())
            assert all(not (a & b) for i, a in enumerate(people) for b in people[i + 1 :])
        # every acknowledged post is in the database, with its annotator
        stored = {q.id: who for q, who, *_ in tables.answered_by()}
        for annotator in annotators:
            for question_id, _, status in annotator.posts:
                if status == 200:
                    assert stored[question_id] == annotator.name_
        # second opinions are somebody else's than the answer they repeat
        author = {(s, i): who for s, _, who, _, _, i in chains}
        assert seconds, "an overlap of 0.5 over 24 answers asked no second opinion"
        for session, index, who in seconds:
            assert who != author[(session, index)]
    finally:
        page.close()


def test_a_member_who_stops_answering_has_their_chain_handed_over(tmp_path):
    page = TeamPage(tmp_path / "labels", TEAM, "sequential", questions=12, reassign_after=1.0)
    try:
        leaver = Annotator(page, "carol", stop_after=2)
        run_team(page, [Annotator(page, "alice"), Annotator(page, "bob"), leaver])
        chains, _ = chain_answers(page)
        assert len(chains) == 12  # the session was answered whole
        assert sum(who == "carol" for _, _, who, *_ in chains) == 2
        stored = page.hub.crowd.tables.chains("offline", 0)
        handed = [c for c in stored if c.parent is not None]
        assert handed and handed[0].owner in ("alice", "bob")
        view = page.client("operator").get("/api/operator").json()
        by_name = {p["name"]: p for p in view["annotators"]}
        assert by_name["carol"]["handed_over"] == 1 and by_name["carol"]["answers"] == 2
    finally:
        page.close()


def test_a_late_joiner_gets_work_at_the_next_question(tmp_path):
    page = TeamPage(tmp_path / "labels", TEAM, "pairwise", questions=12, overlap=0.0)
    try:
        early = [Annotator(page, "alice", pace=0.3), Annotator(page, "bob", pace=0.3)]
        for annotator in early:
            annotator.start()
        for _ in range(600):  # carol arrives once the others are answering
            if early[0].posts:
                break
            page.done.wait(0.05)
        assert early[0].posts and not page.done.is_set()
        carol = Annotator(page, "carol")
        run_team(page, [carol])
        for annotator in early:
            annotator.join(10)
        chains, _ = chain_answers(page)
        assert len(chains) == 12
        assert sum(who == "carol" for _, _, who, *_ in chains) > 0  # the free chain was hers
    finally:
        page.close()


def test_tokens_are_people_one_cannot_act_as_another_and_the_operator_page_is_the_operators(
    tmp_path,
):
    page = TeamPage(tmp_path / "labels", ["alice", "bob"], "root", questions=4)
    try:
        alice, bob, operator = page.client("alice"), page.client("bob"), page.client("operator")
        state = _wait_question(alice)
        question = state["question"]["id"]
        body = {"question_id": question, "choice": "left", "latency_ms": 5}
        refused = bob.post("/api/answer", json=body)
        assert refused.status_code == 403 and "another annotator's" in refused.json()["detail"]
        assert operator.post("/api/answer", json=body).status_code == 403
        # the same annotator in two tabs: one question stream
        second_tab = page.client("alice")
        assert second_tab.get("/api/state").json()["question"]["id"] == question
        assert alice.post("/api/answer", json=body).status_code == 200
        again = second_tab.post("/api/answer", json=body)
        assert again.status_code == 200 and again.json()["duplicate"] is True
        # a token of nobody, and annotators on the operator page, are refused
        stranger = page.client("alice")
        stranger.headers["X-Seqrank-Token"] = "x" * 24
        assert stranger.get("/api/state").status_code == 401
        assert alice.get("/operator").status_code == 403
        assert alice.get("/api/operator").status_code == 403
        assert operator.get("/operator").status_code == 200
        # every answer is the operator's to read, not an annotator's
        assert alice.get("/api/labels.jsonl").status_code == 403
        assert operator.get("/api/labels.jsonl").status_code == 200
        view = operator.get("/api/operator").json()
        assert [p["name"] for p in view["annotators"]] == ["alice", "bob"]
        alice_row = view["annotators"][0]
        assert alice_row["answers"] == 1 and page.hub.crowd.tokens["alice"] in alice_row["address"]
        assert "alice" in [chain["owner"] for chain in view["chains"]]
    finally:
        page.close()


def test_a_chain_question_index_shows_its_place_in_the_chain(tmp_path):
    page = TeamPage(tmp_path / "labels", ["alice", "bob"], "sequential", questions=6, overlap=0.0)
    try:
        state = _wait_question(page.client("alice"))
        assert (state["question"]["index"], state["question"]["questions"]) == (1, 3)
        stored = page.hub.db.question(state["question"]["id"])
        assert stored is not None and key_of(stored.index) in (ChainStep(0, 0), ChainStep(1, 0))
    finally:
        page.close()


def _wait_question(client, tries: int = 600) -> dict:
    import time

    for _ in range(tries):
        state = client.get("/api/state").json()
        if state["status"] == "question":
            return state
        time.sleep(0.05)
    raise AssertionError("no question was shown")


def start_offline_team(directory, names: str):
    """`seqrank label offline --annotators NAMES` as a process, and each page's address."""
    command = [
        "label", "offline", "--task", "dmc:cartpole_swingup", "--scheme", "sequential",
        "--questions", "8", "--episodes", "1", "--port", "0", "--annotators", names,
        "--out", str(directory),
    ]  # fmt: skip
    return start_team(command, tuple(names.split(",")))


def _post(address: str, path: str, body=None):
    import httpx

    base, _, token = address.partition("?token=")
    base = base.replace("/operator", "/").rstrip("/")
    headers = {"X-Seqrank-Token": token}
    if body is None:
        return httpx.get(f"{base}{path}", headers=headers)
    return httpx.post(f"{base}{path}", json=body, headers=headers)


def test_a_team_killed_outright_keeps_every_acknowledged_answer_and_the_same_addresses(tmp_path):
    import signal
    import time

    directory = tmp_path / "labels"
    process, addresses = start_offline_team(directory, "alice,bob")
    acknowledged = {}
    try:
        assert set(addresses) == {"operator", "alice", "bob"}
        for name in ("alice", "bob", "alice"):
            for _ in range(600):
                state = _post(addresses[name], "/api/state").json()
                if state["status"] == "question":
                    break
                time.sleep(0.05)
            body = {"question_id": state["question"]["id"], "choice": "left", "latency_ms": 9}
            reply = _post(addresses[name], "/api/answer", body)
            assert reply.status_code == 200
            acknowledged[state["question"]["id"]] = name
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait(10)
    process, again = start_offline_team(directory, "alice,bob")
    try:
        # the annotators' tokens are kept: their bookmarked pages keep working (the port is
        # a free one each time here; the operator's token is new unless --token gives it)
        for name in ("alice", "bob"):
            assert again[name].partition("?token=")[2] == addresses[name].partition("?token=")[2]
        from seqrank.labelling.db import LabelDB

        db = LabelDB(directory / "labels.sqlite")
        stored = {q.id: a.annotator for q, a in db.answered_questions()}
        db.close()
        assert stored == acknowledged
        state = _post(again["alice"], "/api/state").json()
        for _ in range(600):
            if state["status"] == "question":
                break
            time.sleep(0.05)
            state = _post(again["alice"], "/api/state").json()
        assert state["question"]["id"] not in acknowledged  # asked on from where it stood
    finally:
        process.send_signal(signal.SIGINT)
        process.wait(60)
