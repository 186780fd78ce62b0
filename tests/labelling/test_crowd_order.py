"""A team at the labelling page in collection order (`--segment-order collection`): the
page replays its stored choices around the in-order choice, and the ordered pool is dealt
to the members' chains in turn, so each member meets early and late segments."""

from __future__ import annotations

from dataclasses import replace
from threading import Event

from seqrank.feedback.schemes import in_order_choice
from support.crowd import answering, bare_team, team_request

TEAM = ["alice", "bob", "carol"]


def _lower_first(question) -> str:
    return "left" if question.left == min(question.first, question.second) else "right"


def test_a_team_in_collection_order_is_dealt_the_pool(tmp_path):
    hub = bare_team(tmp_path, TEAM, 60.0)
    request = replace(team_request("root", 30, 3), chooser=in_order_choice, in_order=True)
    done = Event()
    people = [answering(hub, name, _lower_first, done) for name in TEAM]
    try:
        _, record = hub.source("offline", 0).ask_session(request)
    finally:
        done.set()
        for person in people:
            person.join(10)
    chains = hub.crowd.tables.chains("offline", 0)
    hub.db.close()
    assert record.asked == 30 and len(chains) == 3
    usable = sum(len(chain.pool) for chain in chains)
    for chain in chains:  # dealt: each chain spans the pool, early to late
        assert min(chain.pool) < 3 and max(chain.pool) > 0.75 * usable, chain.pool
