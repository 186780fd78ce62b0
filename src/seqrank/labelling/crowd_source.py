"""A team at the labelling page: a session's chains answered side by side, one a person.

Each chain of the session (`seqrank.feedback.crowd.share_session`) runs its scheme in a
thread of its own; its `ask` stores the question, puts it to the chain's owner (or to
whoever is free first, who then owns the chain) and waits for the answer. A question left
unanswered for `reassign_after` seconds is withdrawn and its chain cut: what the chain had
left to ask is handed over as a new chain, which starts afresh from a new first segment
(so a chain never mixes people) and goes to the first annotator free. Second opinions are
posed beside the chains, to anybody but the first answer's author, and never waited for:
those unanswered when the chains are done are withdrawn.

Replay after a kill works as for one person (`seqrank.labelling.human`): pools, chains,
choices, questions and hand-overs are stored before they are used, so the same session
asks the same questions again and stored answers come back at once.
The clocks of questions pending at the kill restart at the server's start: downtime never
hands a question over.
"""

from __future__ import annotations

import secrets
import threading
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import suppress
from dataclasses import dataclass, field, replace

import numpy as np

from seqrank.episodes import Segments
from seqrank.feedback.crowd import Chain, merge_chains, run_chain, share_session, with_opinions
from seqrank.feedback.crowd_record import SecondOpinion
from seqrank.feedback.schemes import (
    Ask,
    Chooser,
    SessionRecord,
    scheme_has_defender,
    segments_needed,
)
from seqrank.feedback.session import SessionRequest
from seqrank.labelling.crowd_db import CHAIN_STRIDE, ChainRow, CrowdTables
from seqrank.labelling.crowd_settings import CrowdSettings
from seqrank.labelling.db import StoredQuestion
from seqrank.labelling.human import Hub, HumanSource, Stopped, stored_session
from seqrank.types import Answer, AnsweredQuestion, Question


def open_team(hub: Hub, names: Sequence[str], overlap: float, reassign_after: float) -> None:
    """Make `hub` a team's page: each annotator with their own token (kept in the database,
    so that a resumed run's addresses stay the same), the main token the operator's; the
    questions pending when the server stopped wait `reassign_after` again from now."""
    tables = CrowdTables(hub.db)
    tables.restart_clocks()  # the time the server was down is nobody's delay
    known = tables.annotators()
    tables.add_annotators({n: known.get(n) or secrets.token_urlsafe(18) for n in names})
    stored = tables.annotators()
    tokens = {name: stored[name] for name in names}
    if hub.settings.token is None:  # a team's page always has tokens, on loopback too
        hub.settings.token = secrets.token_urlsafe(24)
    hub.crowd = CrowdSettings(tokens, hub.settings.token, tables, overlap, reassign_after)


def page_source(hub: Hub, run: str, seed: int) -> HumanSource | CrowdHumanSource:
    """Who answers at the page: its team, or the one person."""
    return HumanSource(hub, run, seed) if hub.crowd is None else CrowdHumanSource(hub, run, seed)


def team_addresses(hub: Hub, base: str) -> list[tuple[str, str]]:
    """(who, address) of the operator page and of each annotator's page."""
    assert hub.crowd is not None
    rows = [("operator", f"{base}operator?token={hub.crowd.operator_token}")]
    rows += [(name, f"{base}?token={token}") for name, token in hub.crowd.tokens.items()]
    return rows


class _Cut(Exception):
    """The chain's question was handed over: the chain ends here."""


@dataclass
class _Asked:
    """What one chain (until a cut) asked and heard, in pool ids."""

    answers: list[AnsweredQuestion] = field(default_factory=list)

    def record(self, scheme: str) -> SessionRecord:
        drawn = [s for a in self.answers for s in (a.first, a.second)]
        return SessionRecord(scheme, tuple(self.answers), tuple(dict.fromkeys(drawn)))


class CrowdHumanSource:
    """Feedback from a team at the page. `run` names the training run in the database."""

    def __init__(self, hub: Hub, run: str, seed: int):
        assert hub.crowd is not None
        self.hub, self.run, self.seed = hub, run, seed
        self.crowd, self.tables = hub.crowd, hub.crowd.tables
        self._lock = threading.Lock()  # chains cut at once take their continuations in turn

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        db, run = self.hub.db, self.run
        row = stored_session(db, run, self.seed, request)
        pool = db.pool(run, request.session)
        session = _CrowdSession(self, request, pool, int(row["seed"]), int(row["questions"]))
        self.hub.run, self.hub.scheme = run, request.scheme
        self.hub.upcoming = sorted(session.segment_ids.values())
        if self.hub.renderer is not None:
            self.hub.renderer.ahead(self.hub.upcoming)
        self.hub.set_phase("asking", f"session {request.session + 1}: the team is answering")
        started = time.time()
        chains = session.first_chains()
        with ThreadPoolExecutor(len(chains), thread_name_prefix="chain") as threads:
            done = list(threads.map(session.run_chain, chains))
        results = [result for chain in done for result in chain]
        record = merge_chains(request.scheme, [r for r, _ in results], [o for _, o in results])
        opinions = session.second_opinions()
        times = session.person_seconds()
        record = with_opinions(session.stored_request(), record, opinions, times)
        assert record.crowd is not None
        crowd = replace(record.crowd, seconds=time.time() - started)
        self.hub.set_phase("training", f"session {request.session + 1} is answered: thank you")
        return pool, replace(record, crowd=crowd)


class _CrowdSession:
    """One session's chains, their questions and hand-overs, and its second opinions."""

    def __init__(
        self,
        source: CrowdHumanSource,
        request: SessionRequest,
        pool: Segments,
        seed: int,
        questions: int,
    ):
        self.source, self.request, self.seed, self.questions = source, request, seed, questions
        self.db, self.tables, self.run = source.hub.db, source.tables, source.run
        self.session = request.session
        self.segment_ids = self.db.segment_ids(self.run, self.session)
        self.pool_size = len(pool.features)
        self.same_pool = np.array_equal(pool.features, request.segments.features)
        self.defender = scheme_has_defender(request.scheme)
        self.failed = threading.Event()

    def stored_request(self) -> SessionRequest:
        """The request with the model's opinions stored with the session (a resumed run
        may sample another pool)."""
        return replace(self.request, model_returns=self.db.model_returns(self.run, self.session))

    def first_chains(self) -> list[ChainRow]:
        stored = [c for c in self.tables.chains(self.run, self.session) if c.parent is None]
        if stored:
            return stored
        shares = self._shares(len(self.source.crowd.annotators))
        return [
            self.tables.add_chain(
                ChainRow(self.run, self.session, k, None, c.budget, c.pool_ids, None)
            )
            for k, c in enumerate(shares)
        ]

    def _shares(self, people: int) -> list[Chain]:
        """The session's chains for `people`, or for as many as its stored pool allows (a
        session stored before the team grew)."""
        scheme = self.request.scheme
        while people > 1 and segments_needed(scheme, self.questions, people) > self.pool_size:
            people -= 1
        return share_session(scheme, self.questions, self.pool_size, people)[0]

    def run_chain(self, chain: ChainRow | None) -> list[tuple[SessionRecord, str]]:
        """The chain and whatever continues it after hand-overs: (record, its author)."""
        results = []
        while chain is not None:
            asked = _Asked()
            rng = np.random.default_rng([self.seed, 7, chain.chain])
            request = replace(self.request, chooser=self._chooser(chain.chain))
            share = Chain(chain.pool, chain.budget)
            try:
                chain_record = run_chain(request, share, self._ask(chain, asked), rng)
                next_chain = None
            except _Cut:
                chain_record = asked.record(self.request.scheme)
                next_chain = self._continuation(chain, asked)
            except BaseException:
                self.failed.set()  # the other chains stop waiting too
                raise
            self.tables.finish_chain(self.run, self.session, chain.chain)
            owner = self.tables.chain_owner(self.run, self.session, chain.chain)
            if chain_record.answers:
                results.append((chain_record, owner or ""))
            chain = next_chain
        return results

    # ---- asking ------------------------------------------------------------------
    def _chooser(self, chain: int) -> Chooser:
        """The session's chooser, its choices stored under the chain's keys and given back
        in order on a replay."""
        made = {"k": 0}
        base = self.request.chooser

        def choose(defender: int | None, available: Sequence[int], rng: np.random.Generator) -> int:
            key = chain * CHAIN_STRIDE + made["k"]
            made["k"] += 1
            replayed = self._stored_choice(key)
            if replayed is not None:
                return replayed
            if self.same_pool:
                position = base(defender, available, rng)
            else:  # the stored pool is not the sampled one (a resumed GPU run)
                position = int(rng.integers(len(available)))
            self.db.add_choice(self.run, self.session, key, position)
            return position

        return choose

    def _stored_choice(self, key: int) -> int | None:
        rows = self.db.rows(
            "SELECT position FROM choices WHERE run = ? AND session = ? AND k = ?",
            self.run, self.session, key,
        )  # fmt: skip
        return int(rows[0]["position"]) if rows else None

    def _ask(self, chain: ChainRow, asked: _Asked) -> Ask:
        def ask(first: int, second: int) -> Answer:
            index = chain.chain * CHAIN_STRIDE + len(asked.answers)
            question = self._store_question(index, first, second, chain.chain)
            owner = self.tables.chain_owner(self.run, self.session, chain.chain)
            self.tables.pose(question, chain.chain, owner, None)
            answer, author = self._wait(question)
            q = Question(len(asked.answers), first, second, self.defender)
            asked.answers.append(AnsweredQuestion(q, answer))
            self._maybe_second_opinion(index, first, second, answer, author)
            return answer

        return ask

    def _store_question(self, index: int, first: int, second: int, chain: int) -> StoredQuestion:
        a, b = self.segment_ids[first], self.segment_ids[second]
        if self.defender and chain >= 0:  # the defender keeps its side all chain long
            on_left = np.random.default_rng([self.seed, 8, chain]).random() < 0.5
        else:
            on_left = np.random.default_rng([self.seed, 10, abs(index)]).random() < 0.5
        left, right = (a, b) if on_left else (b, a)
        defender = a if self.defender else None
        return self.db.ensure_question(self.run, self.session, index, a, b, defender, left, right)

    def _wait(self, question: StoredQuestion) -> tuple[Answer, str]:
        """The answer and its author; _Cut when the question is handed over first."""
        hub, patience = self.source.hub, self.source.crowd.reassign_after
        with self.db.changed:
            while not hub.stop.is_set() and not self.failed.is_set():
                stored = self.db.answer(question.id)
                if stored is not None:
                    return Answer(stored.answer), stored.annotator
                found = self.tables.assignment(question.id)
                if found is not None and found.withdrawn:
                    raise _Cut
                since = None if found is None else found.assigned_at
                overdue = since is not None and time.time() - since > patience
                if overdue and self.tables.withdraw_if_unanswered(question.id):
                    raise _Cut
                self.db.changed.wait(0.5)
        raise Stopped("the labelling server stopped")

    def _maybe_second_opinion(
        self, index: int, first: int, second: int, answer: Answer, author: str
    ) -> None:
        crowd = self.source.crowd
        if answer is Answer.SKIP or len(crowd.annotators) < 2 or crowd.overlap <= 0:
            return
        if np.random.default_rng([self.seed, 9, index]).random() >= crowd.overlap:
            return
        question = self._store_question(-(index + 1), first, second, -1)
        self.tables.pose(question, -1, None, excluded=author)

    # ---- hand-overs --------------------------------------------------------------
    def _continuation(self, chain: ChainRow, asked: _Asked) -> ChainRow | None:
        """The chain that asks what `chain` had left, from the segments its answers did
        not use and one of the session's reserve; None when nothing is left."""
        with self.source._lock:
            stored = self.tables.chains(self.run, self.session)
            for c in stored:
                if c.parent == chain.chain:
                    return c
            used = {s for a in asked.answers for s in (a.first, a.second)}
            pool = [s for s in chain.pool if s not in used]
            pool += self._reserve_segment(stored)
            left = chain.budget - len(asked.answers)
            budget = max(0, min(left, _fits(self.request.scheme, len(pool))))
            if budget == 0:
                return None
            number = max(c.chain for c in stored) + 1
            row = ChainRow(self.run, self.session, number, chain.chain, budget, tuple(pool), None)
            return self.tables.add_chain(row)

    def _reserve_segment(self, stored: list[ChainRow]) -> list[int]:
        first = [c for c in stored if c.parent is None]
        used = {s for c in first for s in c.pool}
        reserve = [s for s in range(self.pool_size) if s not in used]
        taken = {s for c in stored if c.parent is not None for s in c.pool}
        free = [s for s in reserve if s not in taken]
        return free[:1]

    # ---- the session's end -------------------------------------------------------
    def second_opinions(self) -> list[SecondOpinion]:
        """The second opinions given: those nobody took are withdrawn, those taken are
        waited for (as a chain's question is, up to `reassign_after`)."""
        for open_question in self.tables.unanswered(self.run, self.session):
            if open_question.chain >= 0:
                continue
            if open_question.annotator is None:
                self.tables.withdraw_if_unanswered(open_question.question.id)
                continue
            with suppress(_Cut):
                self._wait(open_question.question)
        pool_of = {segment: pool_id for pool_id, segment in self.segment_ids.items()}
        opinions = []
        for question, who, chain, answer, _ in self.tables.answered_by():
            if chain >= 0 or question.run != self.run or question.session != self.session:
                continue
            first, second = pool_of[question.first], pool_of[question.second]
            q = Question(-(question.index + 1), first, second, self.defender)
            opinions.append(SecondOpinion(AnsweredQuestion(q, Answer(answer)), who))
        return opinions

    def person_seconds(self) -> dict[str, float]:
        """Each annotator's answering time in the session (their latencies added up)."""
        times: dict[str, float] = {}
        for question, who, _, _, latency in self.tables.answered_by():
            if question.run == self.run and question.session == self.session:
                times[who] = times.get(who, 0.0) + latency / 1000.0
        return times


def _fits(scheme: str, segments: int) -> int:
    """The most questions of `scheme` that `segments` distinct segments allow."""
    budget = 0
    while segments_needed(scheme, budget + 1) <= segments:
        budget += 1
    return budget
