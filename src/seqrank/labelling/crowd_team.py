"""A team at the labelling page: its annotators, their tokens, and how the page serves
them (`Team`, the page's mode); the sessions themselves are `crowd_source`'s."""

from __future__ import annotations

import secrets
from collections.abc import Sequence
from typing import TYPE_CHECKING

from seqrank.labelling.access import OPERATOR
from seqrank.labelling.crowd_db import CrowdTables, NotYours
from seqrank.labelling.crowd_settings import CrowdSettings
from seqrank.labelling.crowd_source import CrowdHumanSource
from seqrank.labelling.db import StoredAnswer, StoredQuestion
from seqrank.labelling.gold import GoldPairs, store_gold, stored_gold
from seqrank.labelling.human import Hub

if TYPE_CHECKING:
    from fastapi import APIRouter


def open_team(
    hub: Hub,
    names: Sequence[str],
    overlap: float,
    reassign_after: float,
    overlap_until: int = 0,
    gold: GoldPairs | None = None,
) -> None:
    """Make `hub` a team's page: each annotator with their own token (kept in the database,
    so that a resumed run's addresses stay the same), the main token the operator's; the
    questions pending when the server stopped wait `reassign_after` again from now.
    `overlap_until`: the adaptive overlap (`CrowdSettings`); `gold`: pairs of known order
    shown among the members' questions (`seqrank.labelling.gold`; None: those the
    directory was started with, if any)."""
    hub.check_mode_open()  # before the tokens are stored
    gold_pairs = stored_gold(hub.db) if gold is None else store_gold(hub.db, gold)
    tables = CrowdTables(hub.db)
    tables.restart_clocks()  # the time the server was down is nobody's delay
    known = tables.annotators()
    tables.add_annotators({n: known.get(n) or secrets.token_urlsafe(18) for n in names})
    stored = tables.annotators()
    tokens = {name: stored[name] for name in names}
    if hub.settings.token is None:  # a team's page always has tokens, on loopback too
        hub.settings.token = secrets.token_urlsafe(24)
    settings = CrowdSettings(
        tokens, hub.settings.token, tables, overlap, reassign_after, overlap_until, gold_pairs
    )
    hub.choose_mode(Team(settings))


class Team:
    """A team at the page (`human.PageMode`): each annotator answers the questions claimed
    for them, the operator watches on `/operator`."""

    def __init__(self, settings: CrowdSettings):
        self.settings = settings

    @property
    def team(self) -> CrowdSettings:
        return self.settings

    def source(self, hub: Hub, run: str, seed: int) -> CrowdHumanSource:
        return CrowdHumanSource(hub, self.settings, run, seed)

    def tokens(self) -> tuple[tuple[str, str], ...]:
        return tuple(self.settings.tokens.items())

    def question_for(self, hub: Hub, who: str | None) -> StoredQuestion | None:
        if who is None or who == OPERATOR:
            return None
        return self.settings.tables.claim(who)

    def record_answer(
        self, hub: Hub, question: StoredQuestion, choice: str, latency_ms: float, who: str | None
    ) -> tuple[StoredAnswer, bool]:
        if who == OPERATOR:
            raise NotYours("the operator's token answers no questions")
        return self.settings.tables.record_answer(question, choice, latency_ms, who or "")

    def place(self, question: StoredQuestion, questions: int) -> tuple[int, int]:
        return self.settings.tables.progress(question)  # a chain's k-th, or a second opinion

    def routes(self, hub: Hub) -> list[APIRouter]:
        from seqrank.labelling.crowd_report import operator_routes

        return [operator_routes(hub)]

    def may_export(self, who: str | None) -> bool:
        return who == OPERATOR  # every answer is the operator's to read, not an annotator's

    def still_asking(self, hub: Hub) -> bool:
        return True  # a team's session leaves the asking phase itself when it is answered

    def announce(
        self, *, base: str, url: str, remote_base: str | None, remote_url: str | None
    ) -> list[str]:
        return [f"{who}'s page: {address}" for who, address in self.addresses(remote_base or base)]

    def addresses(self, base: str) -> list[tuple[str, str]]:
        """(who, address) of the operator page and of each annotator's page."""
        rows = [("operator", f"{base}operator?token={self.settings.operator_token}")]
        rows += [(name, f"{base}?token={token}") for name, token in self.settings.tokens.items()]
        return rows


def team_addresses(hub: Hub, base: str) -> list[tuple[str, str]]:
    """(who, address) of the operator page and of each annotator's page."""
    return Team(hub.crowd).addresses(base)
