"""Feedback efficiency of every scheme under every scripted teacher, on synthetic segments.

Each session draws a fresh pool of 2N synthetic segments (N = questions per session).
A segment's per-step rewards are `q * (1 + slope * (t/H - 1/2)) + noise`, clipped to
[0, 1], with quality q = U(0, 1) squared (skewed low, as early in training, so that a skip
teacher has low-return pairs to skip), slope ~ N(0, 1) and noise ~ N(0, 0.02). The
within-segment trend is what makes a myopic teacher err.
With `augment checked` the scheme re-checks answers and the closure limits unrepeated
answers on a path, by default with `seqrank train`'s settings (`Recheck()`); a cell's
sessions are one teacher's, in order, so once the teacher has contradicted themselves the
next sessions ask big answers twice more, as in a training run.
A crowd (`crowd:oracle+noisy`) gathers evidence of its members' reliability as in a run
(`CrowdSettings`: the overlap, its adaptive part, closure checks), and each member's
estimate is the one training and the operator page use
(`seqrank.feedback.peer_reliability`), from the same evidence as training's label store.
The teacher's margin is the mean segment return of the pool (the stand-in for "mean
return of recent episodes scaled to segment length"). Truth for error rates is the
undiscounted segment return.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from seqrank.episodes import Segments
from seqrank.feedback.checking import Recheck
from seqrank.feedback.closure import AugmentationStats, augment
from seqrank.feedback.crowd import CrowdSource
from seqrank.feedback.crowd_record import EvidenceRow, session_evidence
from seqrank.feedback.overlap import EVIDENCE_UNTIL, OVERLAP
from seqrank.feedback.peer_reliability import estimate_from_peers
from seqrank.feedback.reliability import evidence_rows
from seqrank.feedback.schemes import get_scheme, uniform_choice
from seqrank.feedback.session import SessionRequest
from seqrank.feedback.sources import make_source
from seqrank.feedback.teachers import CROWD_PREFIX, ScriptedTeacher, scripted_config
from seqrank.types import Answer, AnsweredQuestion

SEGMENT_LENGTH = 50
AUGMENTS = ("full", "checked")
# an answer as reliability evidence: (first, second) made unique per run, answer,
# annotator, the model's P(first) (none: there is no model here)


@dataclass(frozen=True)
class CrowdSettings:
    """How a crowd gathers evidence of its members' reliability, with `seqrank train`'s
    defaults: `overlap` a share of answers asked again, every answer of a member with fewer
    than `overlap_until` shared answers asked again, `closure_checks` second opinions on
    inferred pairs (`seqrank.feedback.sources.make_source`)."""

    overlap: float = OVERLAP
    overlap_until: int = EVIDENCE_UNTIL
    closure_checks: bool = False

    def source(self, teacher: str) -> CrowdSource:
        """The crowd a `crowd:...` value names, as a run builds it."""
        crowd = make_source(teacher, self.overlap, self.overlap_until, self.closure_checks)
        assert isinstance(crowd, CrowdSource), teacher
        return crowd


def synthetic_segments(count: int, horizon: int, rng: np.random.Generator) -> np.ndarray:
    """Per-step rewards of `count` synthetic segments, shape (count, horizon)."""
    quality = (rng.random(count) ** 2)[:, None]
    slope = rng.normal(0.0, 1.0, count)[:, None]
    time = (np.arange(horizon) / horizon - 0.5)[None, :]
    noise = rng.normal(0.0, 0.02, (count, horizon))
    return np.clip(quality * (1 + slope * time) + noise, 0.0, 1.0)


@dataclass(frozen=True)
class CellResult:
    """Means over sessions for one (scheme, teacher); `*_se` are standard errors."""

    scheme: str
    teacher: str
    augment: str
    sessions: int
    questions: int
    pairs_per_question: float
    pairs_per_question_se: float
    inferred_per_question: float
    inferred_error_rate: float | None
    asked_error_rate: float | None
    max_degree: float
    max_degree_se: float
    mean_degree: float
    unique_segments: float
    skipped_per_session: float
    equal_per_session: float
    cyclic_components_per_session: float
    # a crowd's members: name, reliability estimate with its 95% interval, the answers it
    # rests on, agreement on overlaps, and the true error rate of their strict answers
    members: tuple[dict[str, object], ...] = ()

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def run_session(
    scheme: str,
    teacher: ScriptedTeacher,
    questions: int,
    rng: np.random.Generator,
    horizon: int = SEGMENT_LENGTH,
    recheck: Recheck | None = None,
) -> AugmentationStats:
    return _session(scheme, teacher, questions, rng, horizon, recheck)[0]


def run_sessions(
    scheme: str,
    teacher: ScriptedTeacher,
    questions: int,
    sessions: int,
    rng: np.random.Generator,
    recheck: Recheck | None = None,
) -> list[AugmentationStats]:
    """`sessions` sessions of one teacher: what a re-check learns (the teacher
    contradicted themselves) carries over to the next sessions."""
    stats = []
    for _ in range(sessions):
        session_stats, answers = _session(scheme, teacher, questions, rng, SEGMENT_LENGTH, recheck)
        stats.append(session_stats)
        recheck = recheck and recheck.after(answers)
    return stats


def _session(
    scheme: str,
    teacher: ScriptedTeacher,
    questions: int,
    rng: np.random.Generator,
    horizon: int,
    recheck: Recheck | None,
) -> tuple[AugmentationStats, tuple[AnsweredQuestion, ...]]:
    rewards = synthetic_segments(2 * questions, horizon, rng)
    returns = rewards.sum(axis=1)
    session_teacher = teacher.with_margin(float(returns.mean()))

    def ask(first: int, second: int) -> Answer:
        return session_teacher.answer(rewards[first], rewards[second], rng)

    record = get_scheme(scheme)(len(rewards), questions, ask, rng, uniform_choice, recheck)
    path_unchecked = None if recheck is None else recheck.path_unchecked
    return augment(record.answers, returns.tolist(), path_unchecked).stats, record.answers


def run_crowd_sessions(
    scheme: str,
    crowd: CrowdSource,
    questions: int,
    sessions: int,
    rng: np.random.Generator,
    recheck: Recheck | None,
) -> tuple[list[AugmentationStats], tuple[dict[str, object], ...]]:
    """A crowd's sessions, and each member's estimated reliability (from the other
    members' answers and their own contradictions: no reward model here) beside their true
    error rate."""
    stats: list[AugmentationStats] = []
    evidence: list[EvidenceRow] = []  # in training's order: answers, then implied orders
    answered: list[EvidenceRow] = []
    truth: list[bool] = []  # of each answer, whether its first segment is the better
    for session in range(sessions):
        rewards = synthetic_segments(2 * questions, SEGMENT_LENGTH, rng)
        returns = rewards.sum(axis=1)
        pool = Segments(rewards[:, :, None], rewards, [None] * len(rewards), [None] * len(rewards))
        request = SessionRequest(
            scheme, questions, session, pool, uniform_choice, rng, float(returns.mean()),
            recheck=recheck, chains=len(crowd.members),
        )  # fmt: skip
        _, record = crowd.ask_session(request)
        path_unchecked = None if recheck is None else recheck.path_unchecked
        stats.append(augment(record.answers, returns.tolist(), path_unchecked).stats)
        offset = session * len(rewards)
        assert record.crowd is not None
        found = session_evidence(record.crowd, record.answers, offset.__add__)
        given, implied = found.given, found.implied
        evidence += given + implied
        answered += given
        truth += [returns[f - offset] > returns[s - offset] for f, s, _, _, _ in given]
        recheck = recheck and recheck.after(record.answers)
    return stats, _member_rows(crowd, evidence, answered, truth)


def _member_rows(
    crowd: CrowdSource,
    evidence: list[EvidenceRow],
    answered: list[EvidenceRow],
    truth: list[bool],
) -> tuple[dict[str, object], ...]:
    """Each member's estimate from all the evidence, beside the true error rate of the
    strict answers they gave (an implied order is evidence, not an answer given)."""
    estimates = estimate_from_peers(evidence_rows(evidence))
    rows = []
    for member in crowd.members:
        strict = [
            (answer == "first") != first_better
            for (_, _, answer, who, _), first_better in zip(answered, truth, strict=True)
            if who == member.name and answer in ("first", "second")
        ]
        found = estimates.get(member.name)
        row: dict[str, object] = {"name": member.name, "true_error_rate": _mean(strict)}
        if found is not None:
            row.update(estimate=found.estimate, low=found.low, high=found.high)
            row.update(answers=found.answers, agreement=found.agreement, flagged=found.flagged)
        rows.append(row)
    return tuple(rows)


def _mean(values: list[bool]) -> float | None:
    return float(np.mean(values)) if values else None


def simulate_cell(
    scheme: str,
    teacher_name: str,
    questions: int,
    sessions: int,
    rng: np.random.Generator,
    augment_name: str = "full",
    checking: Recheck | None = None,
    crowd_settings: CrowdSettings = CrowdSettings(),
) -> CellResult:
    """`teacher_name`: a scripted teacher as `--teacher` takes it (a preset, optionally with
    knobs: `mistake,eps_mistake=0.2`), or a crowd of them (`crowd:oracle+noisy`, its
    answers shared out and asked again as in a run, by `crowd_settings`);
    `checking` sets `augment checked`'s re-checks and trusted paths (default Recheck())."""
    recheck = None if augment_name == "full" else checking or Recheck()
    members: tuple[dict[str, object], ...] = ()
    if teacher_name.startswith(CROWD_PREFIX):
        crowd = crowd_settings.source(teacher_name)
        stats, members = run_crowd_sessions(scheme, crowd, questions, sessions, rng, recheck)
    else:
        teacher = ScriptedTeacher(scripted_config(teacher_name))
        stats = run_sessions(scheme, teacher, questions, sessions, rng, recheck)
    ppq = np.array([s.pairs_per_question for s in stats])
    max_deg = np.array([s.max_degree for s in stats], dtype=np.float64)
    inferred = sum(s.inferred for s in stats)
    answered_strict = sum(s.answered - s.equal for s in stats)
    return CellResult(
        scheme=scheme,
        teacher=teacher_name,
        augment=augment_name,
        sessions=sessions,
        questions=questions,
        pairs_per_question=float(ppq.mean()),
        pairs_per_question_se=_se(ppq),
        inferred_per_question=inferred / (sessions * questions),
        inferred_error_rate=_ratio(sum(s.inferred_wrong or 0 for s in stats), inferred),
        asked_error_rate=_ratio(sum(s.asked_wrong or 0 for s in stats), answered_strict),
        max_degree=float(max_deg.mean()),
        max_degree_se=_se(max_deg),
        mean_degree=float(np.mean([s.mean_degree for s in stats])),
        unique_segments=float(np.mean([s.unique_segments for s in stats])),
        skipped_per_session=float(np.mean([s.skipped for s in stats])),
        equal_per_session=float(np.mean([s.equal for s in stats])),
        cyclic_components_per_session=float(np.mean([s.cyclic_components for s in stats])),
        members=members,
    )


def simulate(
    schemes: Sequence[str],
    teachers: Sequence[str],
    questions: int,
    sessions: int,
    seed: int,
    on_cell: Callable[[CellResult], None] | None = None,
    augments: Sequence[str] = ("full",),
    checking: Recheck | None = None,
    crowd_settings: CrowdSettings = CrowdSettings(),
) -> list[CellResult]:
    """Every (scheme, augmentation, teacher) cell. Each (scheme, teacher) has its own
    stream derived from `seed`, which its augmentations share (common random numbers)."""
    streams = np.random.SeedSequence(seed).spawn(len(schemes) * len(teachers))
    results = []
    cells = [(s, t) for s in schemes for t in teachers]
    for (scheme, teacher), stream in zip(cells, streams, strict=True):
        for augment_name in augments:
            rng = np.random.default_rng(stream)
            cell = simulate_cell(
                scheme, teacher, questions, sessions, rng, augment_name, checking, crowd_settings
            )
            results.append(cell)
            if on_cell is not None:
                on_cell(cell)
    return results


def _se(values: np.ndarray) -> float:
    return float(values.std(ddof=1) / math.sqrt(len(values))) if len(values) > 1 else 0.0


def _ratio(numerator: int, denominator: int) -> float | None:
    return numerator / denominator if denominator else None
