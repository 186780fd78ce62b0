"""A crowd answering one run: each session shared out as chains, one chain a person.

The choices this module makes (issue 37; docs/guides/team.md):
- a session's questions are split evenly over its people, and its candidate pool into
  disjoint slices, one a chain: each person runs the session's scheme over their own
  slice, so a sequential, root or ranked chain stays with one person, and since the slices
  share no segment, transitivity is only ever drawn through one person's answers;
- a share `overlap` of the answered questions is asked again of a second person; those
  answers measure agreement and train the model as asked pairs, but never enter a closure;
- a crowd of one asks exactly what a single teacher asks (same pool, same draws);
- under `crowd_weighting` reask, each question of a member flagged before the session
  (`SessionRequest.distrusted`) is asked again of as many who are not as the overlap
  would ask, at least one (the fewest shared answers first, as `overlap.checkers` picks),
  in place of the overlap's opinions on it
  (`overlap.reasked`, the page's rule too): an asked pair of the re-asker's, evidence like
  any second opinion, and never in a closure (a flagged member's chain is what the closure
  drew from).

`CrowdSource` is the simulated crowd of scripted members (`--teacher crowd:...`), whose
answer times give the session's length with its people answering side by side.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from seqrank.episodes import Segments
from seqrank.feedback.closure_checks import chain_inferences, pair_to_check
from seqrank.feedback.crowd_record import CrowdRecord, SecondOpinion
from seqrank.feedback.overlap import adaptive_picks, checkers, reasked, reasks_wanted
from seqrank.feedback.schemes import (
    Ask,
    SessionRecord,
    get_scheme,
    handover_reserve,
    segments_needed,
)
from seqrank.feedback.session import SessionRequest
from seqrank.feedback.teachers import CrowdMember, ScriptedTeacher
from seqrank.types import Answer, AnsweredQuestion, Question


@dataclass(frozen=True)
class Chain:
    """One person's share of a session: the pool ids it draws from and its questions."""

    pool_ids: tuple[int, ...]
    budget: int


def share_session(
    scheme: str, questions: int, pool_size: int, people: int, dealt: bool = False
) -> tuple[list[Chain], tuple[int, ...]]:
    """The session's chains and its hand-over reserve: questions split evenly (the first
    chains take the remainder; no chain for a person beyond the questions), the pool cut
    into contiguous slices in proportion to what each chain needs, or with `dealt` dealt
    out in turn (a pool in collection order: every chain then spans it, early to late,
    where slices would give the first person the oldest segments), its last
    `handover_reserve` segments kept aside. ValueError when the pool is too small."""
    if people < 1:
        raise ValueError(f"a session needs at least one person to answer, got {people}")
    chains = min(people, questions)
    budgets = [questions // chains + (1 if k < questions % chains else 0) for k in range(chains)]
    needs = [segments_needed(scheme, b) for b in budgets]
    reserve = handover_reserve(scheme, questions, chains)
    if pool_size < sum(needs) + reserve:
        raise ValueError(
            f"{scheme}: {chains} chains of {budgets} questions need {sum(needs) + reserve} "
            f"segments, but the pool has {pool_size}"
        )
    usable = pool_size - reserve
    scale = usable // sum(needs)
    sizes = [need * scale for need in needs]
    sizes[-1] += usable - sum(sizes)
    if dealt:
        ids = _dealt(sizes)
    else:
        starts = np.cumsum([0, *sizes])
        ids = [tuple(range(int(starts[k]), int(starts[k + 1]))) for k in range(chains)]
    shares = [Chain(ids[k], budgets[k]) for k in range(chains)]
    return shares, tuple(range(usable, pool_size))


def _dealt(sizes: list[int]) -> list[tuple[int, ...]]:
    """Pool ids 0, 1, ... dealt to chains in turn, each until it holds its size."""
    held: list[list[int]] = [[] for _ in sizes]
    turn, position = 0, 0
    while position < sum(sizes):
        if len(held[turn]) < sizes[turn]:
            held[turn].append(position)
            position += 1
        turn = (turn + 1) % len(sizes)
    return [tuple(chain) for chain in held]


def run_chain(
    request: SessionRequest, chain: Chain, ask: Ask, rng: np.random.Generator
) -> SessionRecord:
    """The session's scheme over the chain's slice only, with its chooser and re-check
    seeing pool ids; the record comes back in pool ids."""
    ids = chain.pool_ids

    def ask_local(first: int, second: int) -> Answer:
        return ask(ids[first], ids[second])

    def choose_local(
        defender: int | None, available: Sequence[int], rng: np.random.Generator
    ) -> int:
        known = None if defender is None else ids[defender]
        return request.chooser(known, [ids[i] for i in available], rng)

    recheck = request.recheck
    if recheck is not None and recheck.model_returns is not None:
        opinions = recheck.model_returns
        recheck = replace(recheck, model_returns=tuple(opinions[i] for i in ids))
    scheme = get_scheme(request.scheme)
    record = scheme(len(ids), chain.budget, ask_local, rng, choose_local, recheck)
    return _in_pool_ids(record, ids)


def _in_pool_ids(record: SessionRecord, ids: tuple[int, ...]) -> SessionRecord:
    answers = tuple(
        AnsweredQuestion(replace(a.question, first=ids[a.first], second=ids[a.second]), a.answer)
        for a in record.answers
    )
    vouched = frozenset((ids[w], ids[loser]) for w, loser in record.vouched)
    return replace(
        record, answers=answers, segments=tuple(ids[s] for s in record.segments), vouched=vouched
    )


def chain_rngs(request: SessionRequest, chains: int) -> list[np.random.Generator]:
    """Each chain's generator: the session's own for a single chain (a crowd of one asks
    what one teacher asks), else seeded from its draws (not `spawn`: a generator's
    restored state, as a resumed run has it, does not carry its spawn count)."""
    if chains == 1:
        return [request.rng]
    seeds = request.rng.integers(2**63, size=chains)
    return [np.random.default_rng(int(seed)) for seed in seeds]


def merge_chains(
    scheme: str, records: Sequence[SessionRecord], owners: Sequence[str]
) -> SessionRecord:
    """One session record of the chains, questions numbered in chain order."""
    answers: list[AnsweredQuestion] = []
    answered_by: list[str] = []
    for record, owner in zip(records, owners, strict=True):
        for asked in record.answers:
            question = replace(asked.question, index=len(answers))
            answers.append(AnsweredQuestion(question, asked.answer))
            answered_by.append(owner)
    return SessionRecord(
        scheme,
        tuple(answers),
        tuple(s for record in records for s in record.segments),
        frozenset().union(*(record.vouched for record in records)),
        crowd=CrowdRecord(tuple(answered_by)),
    )


def model_first(request: SessionRequest, first: int, second: int) -> float | None:
    """The model's P(first preferred) before the session (None before its first fit)."""
    returns = request.model_returns
    if returns is None:
        return None
    difference = float(np.clip(returns[first] - returns[second], -50.0, 50.0))
    return 1.0 / (1.0 + math.exp(-difference))


def with_opinions(
    request: SessionRequest,
    record: SessionRecord,
    second_opinions: Sequence[SecondOpinion],
    times: dict[str, float],
) -> SessionRecord:
    """The record with its second opinions, the model's view of each asked pair and the
    session's times (`times`: each person's answering seconds)."""
    assert record.crowd is not None
    asked = [*record.answers, *(s.answered for s in second_opinions)]
    crowd = replace(
        record.crowd,
        second_opinions=tuple(second_opinions),
        model_first=tuple(model_first(request, a.first, a.second) for a in asked),
        seconds=max(times.values(), default=0.0),
        person_seconds=sum(times.values()),
    )
    return replace(record, crowd=crowd)


def overlap_picks(
    record: SessionRecord, people: int, overlap: float, rng: np.random.Generator
) -> list[tuple[int, int]]:
    """(answer index, second person's index) for the answers asked again: each answered
    question with probability `overlap`, of someone other than its owner."""
    if people < 2 or overlap <= 0 or record.crowd is None:
        return []
    picks = []
    for k, asked in enumerate(record.answers):
        draw, other = rng.random(), int(rng.integers(people - 1))
        if asked.answer is not Answer.SKIP and draw < overlap:
            picks.append((k, other))
    return picks


class CrowdSource:
    """A simulated crowd: scripted members, each answering its chain, at its own pace.
    `overlap_until` N: every answer of a member with fewer than N answers shared with
    someone else is asked again (`seqrank.feedback.overlap`); 0: a share `overlap` only.
    `closure_checks`: a second opinion asks, where the owner's chain inferred one, a pair
    its closure inferred rather than the asked pair (`seqrank.feedback.closure_checks`)."""

    def __init__(
        self,
        members: Sequence[CrowdMember],
        overlap: float,
        overlap_until: int = 0,
        closure_checks: bool = False,
    ):
        if not members:
            raise ValueError("a crowd needs at least one member")
        self.members, self.overlap = tuple(members), overlap
        self.overlap_until, self.closure_checks = overlap_until, closure_checks
        self.shared: dict[str, int] = {}  # each member's answers shared with others so far

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        rewards = request.segments.rewards
        teachers = [ScriptedTeacher(m.teacher).with_margin(request.margin) for m in self.members]
        in_order = request.in_order  # (collection order: deal the pool)
        chains, _ = share_session(
            request.scheme, request.questions, len(rewards), len(teachers), in_order
        )
        rngs = chain_rngs(request, len(chains))
        answers = dict.fromkeys((m.name for m in self.members), 0)

        def asker(person: int, rng: np.random.Generator) -> Ask:
            def ask(first: int, second: int) -> Answer:
                answers[self.members[person].name] += 1
                return teachers[person].answer(rewards[first], rewards[second], rng)

            return ask

        records = [
            run_chain(request, chain, asker(k, rng), rng)
            for k, (chain, rng) in enumerate(zip(chains, rngs, strict=True))
        ]
        owners = [m.name for m in self.members[: len(chains)]]
        record = merge_chains(request.scheme, records, owners)
        names = [m.name for m in self.members]
        exempt = frozenset(n for n in names if reasked(n, request.distrusted, names))
        seconds = self._second_opinions(record, rngs, asker, exempt)
        seconds += self._reasks(record, exempt, rngs[0], asker)
        times = {m.name: answers[m.name] * m.seconds for m in self.members}
        return request.segments, with_opinions(request, record, seconds, times)

    def _second_opinions(
        self,
        record: SessionRecord,
        rngs: Sequence[np.random.Generator],
        asker: Callable[[int, np.random.Generator], Ask],
        exempt: frozenset[str],
    ) -> list[SecondOpinion]:
        assert record.crowd is not None
        names = [m.name for m in self.members]
        rng = rngs[0]
        inferred = chain_inferences(record) if self.closure_checks else {}
        opinions, checks = [], {}  # (one pair to check per answer, whoever checks it)
        for k, person in self._picks(record, rng, exempt):
            asked, owner = record.answers[k], record.crowd.answered_by[k]
            first, second, implied = asked.first, asked.second, None
            if inferred and k not in checks:
                checks[k] = pair_to_check(inferred.get(owner, []), asked, rng)
            check = checks.get(k)
            if check is not None:
                first, second, implied = check[0], check[1], (owner, check[2])
            question = Question(k, first, second, asked.question.first_is_defender)
            answer = asker(person, rng)(first, second)
            answered = AnsweredQuestion(question, answer)
            opinions.append(SecondOpinion(answered, names[person], implied))
        return opinions

    def _reasks(
        self,
        record: SessionRecord,
        exempt: frozenset[str],
        rng: np.random.Generator,
        asker: Callable[[int, np.random.Generator], Ask],
    ) -> list[SecondOpinion]:
        """Each question of an `exempt` (re-asked) member asked again of as many who are
        not as the overlap would ask (`reasks_wanted`), skipped questions too: the flagged
        member's skip is no answer either."""
        assert record.crowd is not None
        names = [m.name for m in self.members]
        trusted = [name for name in names if name not in exempt]
        until, overlap, reasks = self.overlap_until, self.overlap, []
        for asked, owner in zip(record.answers, record.crowd.answered_by, strict=True):
            if owner not in exempt:
                continue
            wanted = reasks_wanted(self.shared.get(owner, 0), until, overlap, rng.random())
            people = checkers(self.shared, owner, trusted, rng, min(wanted, len(trusted)))
            for name in (owner, *people):
                self.shared[name] = self.shared.get(name, 0) + 1
            for person in people:
                answer = asker(names.index(person), rng)(asked.first, asked.second)
                reasks.append(SecondOpinion(replace(asked, answer=answer), person, reask=True))
        return reasks

    def _picks(
        self, record: SessionRecord, rng: np.random.Generator, exempt: frozenset[str]
    ) -> list[tuple[int, int]]:
        """(answer index, the second person's member index): adaptive, or as before; none
        of an `exempt` member's answers."""
        assert record.crowd is not None
        names = [m.name for m in self.members]
        if self.overlap_until:
            picks = adaptive_picks(
                record, names, self.shared, self.overlap_until, self.overlap, rng, exempt
            )
            return [(k, names.index(second)) for k, second in picks]
        fixed = []
        for k, other in overlap_picks(record, len(names), self.overlap, rng):
            owner = names.index(record.crowd.answered_by[k])
            if names[owner] not in exempt:
                fixed.append((k, other if other < owner else other + 1))
        return fixed
