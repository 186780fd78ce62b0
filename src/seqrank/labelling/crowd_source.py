"""A team at the labelling page: a session's chains answered side by side, one a person.

Each chain of the session (`seqrank.feedback.crowd.share_session`) runs its scheme in a
thread of its own; its `ask` stores the question, puts it to the chain's owner (or to
whoever is free first, who then owns the chain) and waits for the answer. A question left
unanswered for `reassign_after` seconds is withdrawn and its chain cut: what the chain had
left to ask is handed over as a new chain (`crowd_handover`), which starts afresh from a
new first segment (so a chain never mixes people) and goes to the first annotator free.
Other opinions on an answer are posed beside the chains, to anybody but its author (and
nobody gives two on one pair): two others while the author's answers shared with somebody
else are fewer than `overlap_until`, then one at the share `overlap`
(`seqrank.feedback.overlap`). The chains never wait for them; once the chains are done, an
opinion nobody takes within `reassign_after` is withdrawn.

Replay after a kill is the one person's (`session_replay`): pools, chains, choices,
questions and hand-overs are stored before they are used, each under its key
(`crowd_keys`), and every draw comes from a named stream (`streams`), so the same session
asks the same questions again and stored answers come back at once. The clocks of
questions pending at the kill restart at the server's start: downtime never hands a
question over.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import suppress
from dataclasses import dataclass, field, replace
from itertools import count

from seqrank.episodes import Segments
from seqrank.feedback.crowd import Chain, merge_chains, run_chain, share_session, with_opinions
from seqrank.feedback.crowd_record import GoldAnswer, SecondOpinion
from seqrank.feedback.overlap import opinions_wanted, reasked, reasks_wanted
from seqrank.feedback.schemes import (
    Ask,
    SessionRecord,
    scheme_has_defender,
    segments_needed,
)
from seqrank.feedback.session import SessionRequest
from seqrank.labelling.crowd_db import ChainRow
from seqrank.labelling.crowd_handover import continuation
from seqrank.labelling.crowd_keys import (
    GOLD_CHECKS,
    GOLD_RUN,
    REASK_NTH,
    SECOND_OPINIONS,
    ChainStep,
    QuestionKey,
    SecondOpinionOf,
    key_of,
)
from seqrank.labelling.crowd_settings import CrowdSettings
from seqrank.labelling.db import StoredQuestion
from seqrank.labelling.gold import GOLD_SHARE
from seqrank.labelling.human import Hub, Stopped
from seqrank.labelling.page_state import Phase
from seqrank.labelling.session_replay import StoredSession, open_session
from seqrank.labelling.streams import Stream, stream
from seqrank.types import Answer, AnsweredQuestion, Question


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

    def __init__(self, hub: Hub, team: CrowdSettings, run: str, seed: int):
        self.hub, self.team, self.run, self.seed = hub, team, run, seed

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        stored = open_session(self.hub.db, self.run, self.seed, request)
        session = _CrowdSession(self.hub, self.team, stored)
        upcoming = sorted(stored.segment_ids.values())
        upcoming += sorted({s for a, b, _ in self.team.gold for s in (a, b)})  # (clips ready)
        self.hub.state.show_session(self.run, request.scheme, upcoming)
        if self.hub.renderer is not None:
            self.hub.renderer.ahead(upcoming)
        number = request.session + 1
        self.hub.state.move(Phase.ASKING, f"session {number}: the team is answering")
        started = time.time()
        chains = session.first_chains()
        with ThreadPoolExecutor(len(chains), thread_name_prefix="chain") as threads:
            done = list(threads.map(session.run_chain, chains))
        results = [result for chain in done for result in chain]
        record = merge_chains(request.scheme, [r for r, _ in results], [o for _, o in results])
        opinions = session.second_opinions()
        times = session.person_seconds()
        record = with_opinions(stored.request, record, opinions, times)
        assert record.crowd is not None
        gold = tuple(session.gold_answers())
        crowd = replace(record.crowd, seconds=time.time() - started, gold=gold)
        self.hub.state.move(Phase.TRAINING, f"session {number} is answered: thank you")
        return stored.pool, replace(record, crowd=crowd)


class _CrowdSession:
    """One session's chains, their questions and hand-overs, and its second opinions."""

    def __init__(self, hub: Hub, team: CrowdSettings, stored: StoredSession):
        self.hub, self.team, self.tables, self.stored = hub, team, team.tables, stored
        self.db, self.run, self.session = hub.db, stored.run, stored.session
        self.request, self.seed = stored.request, stored.seed
        self.pool_size = len(stored.pool.features)
        self.defender = scheme_has_defender(stored.request.scheme)
        self.failed = threading.Event()

    def first_chains(self) -> list[ChainRow]:
        stored = [c for c in self.tables.chains(self.run, self.session) if c.parent is None]
        if stored:
            return stored
        shares = self._shares(len(self.team.annotators))
        return [
            self.tables.add_chain(
                ChainRow(self.run, self.session, k, None, c.budget, c.pool_ids, None)
            )
            for k, c in enumerate(shares)
        ]

    def _shares(self, people: int) -> list[Chain]:
        """The session's chains for `people`, or for as many as its stored pool allows (a
        session stored before the team grew)."""
        scheme, questions = self.request.scheme, self.stored.questions
        while people > 1 and segments_needed(scheme, questions, people) > self.pool_size:
            people -= 1
        in_order = self.request.in_order  # (collection order: deal it)
        return share_session(scheme, questions, self.pool_size, people, in_order)[0]

    def run_chain(self, chain: ChainRow | None) -> list[tuple[SessionRecord, str]]:
        """The chain and whatever continues it after hand-overs: (record, its author)."""
        results = []
        while chain is not None:
            asked = _Asked()
            rng = stream(self.seed, Stream.CHAIN, chain.chain)
            keys = (ChainStep(chain.chain, k).index for k in count())
            request = replace(self.request, chooser=self.stored.choices.chooser(keys))
            try:
                share = Chain(chain.pool, chain.budget)
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
    def _ask(self, chain: ChainRow, asked: _Asked) -> Ask:
        def ask(first: int, second: int) -> Answer:
            key = ChainStep(chain.chain, len(asked.answers))
            question = self._store_question(key, first, second)
            owner = self.tables.chain_owner(self.run, self.session, chain.chain)
            self.tables.pose(question, chain.chain, owner, None)
            answer, author = self._wait(question)
            q = Question(len(asked.answers), first, second, self.defender)
            asked.answers.append(AnsweredQuestion(q, answer))
            self._maybe_second_opinion(key, first, second, answer, author)
            self._maybe_gold(question, key, author)
            return answer

        return ask

    def _store_question(self, key: QuestionKey, first: int, second: int) -> StoredQuestion:
        a, b = self.stored.segment_ids[first], self.stored.segment_ids[second]
        if self.defender and isinstance(key, ChainStep):  # it keeps its side all chain long
            on_left = stream(self.seed, Stream.CHAIN_DEFENDER_SIDE, key.chain).random() < 0.5
        else:  # (keyed by the index's size, as sessions were first stored)
            on_left = stream(self.seed, Stream.QUESTION_SIDE, abs(key.index)).random() < 0.5
        left, right = (a, b) if on_left else (b, a)
        defender = a if self.defender else None
        return self.db.ensure_question(
            self.run, self.session, key.index, a, b, defender, left, right
        )

    def _wait(self, question: StoredQuestion) -> tuple[Answer, str]:
        """The answer and its author; _Cut when the question is handed over first."""
        patience = self.team.reassign_after
        with self.db.changed:
            while not self.hub.stop.is_set() and not self.failed.is_set():
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
        self, key: ChainStep, first: int, second: int, answer: Answer, author: str
    ) -> None:
        if reasked(author, self.request.distrusted, self.team.annotators):
            self._reask(key, first, second, author)
        else:
            self._overlap(key, first, second, answer, author)

    def _wanted(
        self, key: ChainStep, author: str, rule: Callable[..., int] = opinions_wanted
    ) -> int:
        """How many others `rule` asks about `author`'s answer (uncapped): the overlap's
        `opinions_wanted`, or reask's `reasks_wanted`."""
        team = self.team
        draw = stream(self.seed, Stream.SECOND_OPINION, key.index).random()
        shared = self.tables.shared_answers(self.run, author)
        return rule(shared, team.overlap_until, team.overlap, draw)

    def _reask(self, key: ChainStep, first: int, second: int, author: str) -> None:
        """Under `crowd_weighting` reask, a flagged member's question (a skip too) asked
        again of as many not flagged as the overlap would ask, at least one
        (`reasks_wanted`); their answers train in place of theirs."""
        distrusted = self.request.distrusted
        trusted = [name for name in self.team.annotators if name not in distrusted]
        wanted = self._wanted(key, author, reasks_wanted)
        excluded = ",".join(sorted(distrusted))
        for nth in range(REASK_NTH, REASK_NTH + min(wanted, len(trusted))):
            question = self._store_question(SecondOpinionOf(key, nth), first, second)
            self.tables.pose(question, SECOND_OPINIONS, None, excluded=excluded)

    def _overlap(
        self, key: ChainStep, first: int, second: int, answer: Answer, author: str
    ) -> None:
        """Pose the other opinions on an answer: two while its author's answers shared
        with somebody else are fewer than `overlap_until`, else one at the share
        `overlap`. Replayed with the same settings, it poses nothing it did not pose
        before: a shared count never decreases, so a later decision never asks for more
        (and posing a posed question again changes nothing)."""
        if answer is Answer.SKIP or len(self.team.annotators) < 2:
            return
        wanted = min(self._wanted(key, author), len(self.team.annotators) - 1)
        for nth in range(wanted):
            question = self._store_question(SecondOpinionOf(key, nth), first, second)
            self.tables.pose(question, SECOND_OPINIONS, None, excluded=author)

    def _maybe_gold(self, occasion: StoredQuestion, key: ChainStep, author: str) -> None:
        """Now and then, give the author the next gold pair they have not been shown,
        stored under the id of the answer it follows (so a replay finds it again)."""
        gold = self.team.gold
        if not gold or not author:
            return
        if stream(self.seed, Stream.GOLD, key.index).random() >= GOLD_SHARE:
            return
        question = self.db.question_at(GOLD_RUN, 0, occasion.id)
        if question is None:
            person = self.team.annotators.index(author) if author in self.team.tokens else 0
            order = stream(0, Stream.GOLD_ORDER, person).permutation(len(gold))
            a, b, _ = gold[order[self.tables.gold_given(author) % len(gold)]]
            on_left = stream(self.seed, Stream.QUESTION_SIDE, occasion.id, 1).random() < 0.5
            left, right = (a, b) if on_left else (b, a)
            defender = a if self.defender else None  # (shown as a chain's question is)
            question = self.db.ensure_question(
                GOLD_RUN, 0, occasion.id, a, b, defender, left, right
            )
        self.tables.pose(question, GOLD_CHECKS, author, None)

    def _continuation(self, chain: ChainRow, asked: _Asked) -> ChainRow | None:
        used = {s for a in asked.answers for s in (a.first, a.second)}
        scheme, answered = self.request.scheme, len(asked.answers)
        size = self.pool_size
        return self.tables.continue_chain(
            chain, lambda stored: continuation(scheme, chain, used, answered, stored, size)
        )

    # ---- the session's end -------------------------------------------------------
    def second_opinions(self) -> list[SecondOpinion]:
        """The other opinions given: those nobody takes within `reassign_after` of the
        chains' end are withdrawn, those taken are waited for (as a chain's question is,
        up to `reassign_after`)."""
        deadline = time.time() + self.team.reassign_after
        for open_question in self.tables.unanswered(self.run, self.session):
            if open_question.chain >= 0:
                continue
            if not self._claimed_by(open_question.question, deadline):
                self.tables.withdraw_if_unanswered(open_question.question.id)
                continue
            with suppress(_Cut):
                self._wait(open_question.question)
        pool_of = {segment: pool_id for pool_id, segment in self.stored.segment_ids.items()}
        opinions = []
        for question, who, chain, answer, _ in self.tables.answered_by():
            here = (question.run, question.session) == (self.run, self.session)
            if chain != SECOND_OPINIONS or not here:
                continue
            key = key_of(question.index)
            assert isinstance(key, SecondOpinionOf)
            first, second = pool_of[question.first], pool_of[question.second]
            q = Question(key.asked.index, first, second, self.defender)
            reask = key.nth >= REASK_NTH
            opinions.append(SecondOpinion(AnsweredQuestion(q, Answer(answer)), who, reask=reask))
        return opinions

    def _claimed_by(self, question: StoredQuestion, deadline: float) -> bool:
        """Whether somebody takes (or has taken, or answered) the `question` before
        `deadline`; Stopped when the server stops first (a replay waits again)."""
        with self.db.changed:
            while True:
                found = self.tables.assignment(question.id)
                if found is None or found.withdrawn:
                    return False
                if found.annotator is not None or self.db.answer(question.id) is not None:
                    return True
                if self.hub.stop.is_set():
                    raise Stopped("the labelling server stopped")
                if time.time() >= deadline:
                    return False
                self.db.changed.wait(0.5)

    def person_seconds(self) -> dict[str, float]:
        """Each annotator's answering time in the session (their latencies added up, gold
        questions' too)."""
        times: dict[str, float] = {}
        for question, who, _, _, latency in self.tables.answered_by():
            if question.run == self.run and question.session == self.session:
                times[who] = times.get(who, 0.0) + latency / 1000.0
        for _, who, _, latency in self.tables.gold_answers(self.run, self.session):
            times[who] = times.get(who, 0.0) + latency / 1000.0
        return times

    def gold_answers(self) -> list[GoldAnswer]:
        """The answers to gold questions given after the session's answers."""
        known = {(a, b): Answer.FIRST if first else Answer.SECOND for a, b, first in self.team.gold}
        return [
            GoldAnswer((q.first, q.second), known[q.first, q.second], Answer(said), who)
            for q, who, said, _ in self.tables.gold_answers(self.run, self.session)
            if (q.first, q.second) in known
        ]
