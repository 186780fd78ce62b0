"""Expected numbers of labelled pairs per session (supplementary B.1) and dependency degrees.

For a session on M segments with distinct true values in uniformly random order and a
perfect teacher (M - 1 questions):

- sequential: the paper's recurrence a_M (Lemma 1) and its linear approximation
  1.392 (M - 1.324) (Theorem 1). Exact value: pair (i, j), i < j, is labelled exactly when
  segments i..j are monotone, which has probability 2 / (j - i + 1)!, so
      a_M = sum_{d=1}^{M-1} (M - d) * 2 / (d + 1)!  ->  2 (e - 2) M - 2 as M grows.
  The paper's recurrence treats the tail after the first turn as a fresh sequence, but the
  turning segment is the maximum of the run before it, so the recurrence is not exact
  (it differs from enumeration from M = 4 on).
- root: b_M = 2 (M - H_M) (Theorem 2), which is exact.

Every number is computed three ways where feasible: formula, exhaustive enumeration of all
M! orderings through the real scheme and closure code, and simulation of the real code.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from seqrank.feedback.closure import AugmentationStats, augment
from seqrank.feedback.schemes import Chooser, get_scheme, in_order_choice, uniform_choice
from seqrank.types import Answer

THEORY_SCHEMES = ("sequential", "root")
DEFAULT_MS = (2, 3, 4, 5, 6, 8, 11, 21, 51, 101)
PAPER_SEQUENTIAL_SLOPE = 1.392
PAPER_SEQUENTIAL_INTERCEPT = 1.324
# Figure 13 / section D.6 of the supplementary, measured at M = 101 on quadruped_walk.
PAPER_FIGURE13 = {
    "M": 101,
    "sequential": {"augmented": 38.75, "max_degree": 9.86, "degree_bound": 10.11},
    "root": {"augmented": 91.61, "max_degree": 190.43, "degree_bound": 195.97},
    "delta": 0.03,
}
AGREEMENT_TOLERANCE = 1e-9


def paper_sequential_recurrence(m_max: int) -> list[float]:
    """a_0 .. a_{m_max} from Lemma 1: a_M = 2 - 2/M! + sum_{j=2}^{M-1} a_{M-j+1} 2j/(j+1)!."""
    values = [0.0, 0.0]
    for m in range(2, m_max + 1):
        total = 2.0 - 2.0 / math.factorial(m)
        total += sum(values[m - j + 1] * 2 * j / math.factorial(j + 1) for j in range(2, m))
        values.append(total)
    return values[: m_max + 1]


def paper_sequential_linear(m: int) -> float:
    """Theorem 1's linear approximation 1.392 (M - 1.324)."""
    return PAPER_SEQUENTIAL_SLOPE * (m - PAPER_SEQUENTIAL_INTERCEPT)


def exact_sequential_pairs(m: int) -> float:
    """Exact expected labelled pairs of a sequential session on M segments."""
    return sum((m - d) * 2.0 / math.factorial(d + 1) for d in range(1, m))


def exact_sequential_linear(m: int) -> float:
    """The exact asymptote 2 (e - 2) M - 2 (error below 1e-3 from M = 6 on)."""
    return 2 * (math.e - 2) * m - 2


def root_pairs(m: int) -> float:
    """Theorem 2: b_M = 2 (M - H_M)."""
    return 2 * (m - sum(1.0 / n for n in range(1, m + 1)))


def sequential_degree_bound(m: int, delta: float) -> float:
    """Lemma 3: with probability >= 1 - delta the max degree is at most this."""
    return 2 + math.log(1 + m / math.log(1 / (1 - delta)))


def root_degree_bound(m: int, delta: float) -> float:
    """Lemma 4: with probability >= 1 - delta the max degree is at most this."""
    return m * (2 - delta) - 3


@dataclass(frozen=True)
class SessionCounts:
    """Mean labelled pairs and dependency degrees over a set of orderings."""

    pairs: float
    pairs_se: float
    max_degree: float
    max_degree_se: float
    mean_degree: float
    sessions: int


def perfect_session(
    scheme: str, values: Sequence[float], choose: Chooser, rng: np.random.Generator
) -> AugmentationStats:
    """Run the real scheme and closure on segments with true `values` and a perfect teacher."""

    def ask(first: int, second: int) -> Answer:
        return Answer.FIRST if values[first] > values[second] else Answer.SECOND

    m = len(values)
    record = get_scheme(scheme)(m, m - 1, ask, rng, choose, None)
    return augment(record.answers, values).stats


def _summarise(rows: list[tuple[int, int, float]]) -> SessionCounts:
    data = np.asarray(rows, dtype=np.float64)
    n = len(data)
    se = data.std(axis=0, ddof=1) / math.sqrt(n) if n > 1 else np.zeros(3)
    return SessionCounts(
        pairs=float(data[:, 0].mean()),
        pairs_se=float(se[0]),
        max_degree=float(data[:, 1].mean()),
        max_degree_se=float(se[1]),
        mean_degree=float(data[:, 2].mean()),
        sessions=n,
    )


def enumerate_orderings(scheme: str, m: int) -> SessionCounts:
    """Exact means over all M! orderings, each run through the real scheme code."""
    rng = np.random.default_rng(0)  # unused by the in-order chooser
    rows = []
    for ordering in itertools.permutations(range(m)):
        stats = perfect_session(scheme, ordering, in_order_choice, rng)
        rows.append((stats.labelled, stats.max_degree, stats.mean_degree))
    counts = _summarise(rows)
    return SessionCounts(counts.pairs, 0.0, counts.max_degree, 0.0, counts.mean_degree, len(rows))


def simulate_orderings(
    scheme: str, m: int, sessions: int, rng: np.random.Generator
) -> SessionCounts:
    """Means over random orderings drawn by the real scheme code with uniform challengers."""
    rows = []
    for _ in range(sessions):
        values = rng.random(m).tolist()
        stats = perfect_session(scheme, values, uniform_choice, rng)
        rows.append((stats.labelled, stats.max_degree, stats.mean_degree))
    return _summarise(rows)


@dataclass(frozen=True)
class TheoryRow:
    """All numbers for one M. `*_enumerated` are None when M exceeds the enumeration limit."""

    m: int
    questions: int
    sequential_paper_recurrence: float
    sequential_paper_linear: float
    sequential_exact: float
    sequential_exact_linear: float
    sequential_enumerated: float | None
    sequential_simulated: float
    sequential_simulated_se: float
    sequential_augmented_exact: float
    sequential_augmented_paper: float
    sequential_max_degree_enumerated: float | None
    sequential_max_degree_simulated: float
    sequential_mean_degree_simulated: float
    sequential_degree_bound: float
    root_paper: float
    root_enumerated: float | None
    root_simulated: float
    root_simulated_se: float
    root_augmented: float
    root_max_degree_enumerated: float | None
    root_max_degree_simulated: float
    root_mean_degree_simulated: float
    root_degree_bound: float

    def as_dict(self) -> dict[str, float | int | None]:
        return asdict(self)


def theory_row(
    m: int,
    sessions: int,
    enumerate_max: int,
    delta: float,
    rng: np.random.Generator,
    recurrence: Sequence[float],
) -> TheoryRow:
    enumerated = (
        {s: enumerate_orderings(s, m) for s in THEORY_SCHEMES} if m <= enumerate_max else {}
    )
    simulated = {s: simulate_orderings(s, m, sessions, rng) for s in THEORY_SCHEMES}
    seq_enum, root_enum = enumerated.get("sequential"), enumerated.get("root")
    seq_sim, root_sim = simulated["sequential"], simulated["root"]
    return TheoryRow(
        m=m,
        questions=m - 1,
        sequential_paper_recurrence=recurrence[m],
        sequential_paper_linear=paper_sequential_linear(m),
        sequential_exact=exact_sequential_pairs(m),
        sequential_exact_linear=exact_sequential_linear(m),
        sequential_enumerated=seq_enum.pairs if seq_enum else None,
        sequential_simulated=seq_sim.pairs,
        sequential_simulated_se=seq_sim.pairs_se,
        sequential_augmented_exact=exact_sequential_pairs(m) - (m - 1),
        sequential_augmented_paper=paper_sequential_linear(m) - (m - 1),
        sequential_max_degree_enumerated=seq_enum.max_degree if seq_enum else None,
        sequential_max_degree_simulated=seq_sim.max_degree,
        sequential_mean_degree_simulated=seq_sim.mean_degree,
        sequential_degree_bound=sequential_degree_bound(m, delta),
        root_paper=root_pairs(m),
        root_enumerated=root_enum.pairs if root_enum else None,
        root_simulated=root_sim.pairs,
        root_simulated_se=root_sim.pairs_se,
        root_augmented=root_pairs(m) - (m - 1),
        root_max_degree_enumerated=root_enum.max_degree if root_enum else None,
        root_max_degree_simulated=root_sim.max_degree,
        root_mean_degree_simulated=root_sim.mean_degree,
        root_degree_bound=root_degree_bound(m, delta),
    )


def disagreements(rows: Sequence[TheoryRow], z: float = 4.0) -> list[str]:
    """Plain-language findings, one per formula, where it disagrees with exact values.

    "Exact" is enumeration of all orderings where M is small enough, otherwise the exact
    sequential formula (itself checked against enumeration and simulation here).
    Simulation means are compared within `z` standard errors.
    """
    recurrence, linear = "paper recurrence a_M (Lemma 1)", "paper linear 1.392(M-1.324) (Theorem 1)"
    exact, root = "exact sequential formula", "root b_M = 2(M - H_M) (Theorem 2)"
    enumeration = "enumeration of all orderings"
    formulas: dict[str, list[tuple[int, float, float, str]]] = {}
    for row in rows:
        seq_truth, seq_source = row.sequential_enumerated, enumeration
        if seq_truth is None:
            seq_truth, seq_source = row.sequential_exact, "the exact formula"
        # the paper claims the linear form is off by less than 0.003 from M = 4 on
        linear_off = row.m >= 4 and abs(row.sequential_paper_linear - seq_truth) > 0.003
        against_exact = (
            (recurrence, row.sequential_paper_recurrence, seq_truth, seq_source),
            (linear, row.sequential_paper_linear, seq_truth if linear_off else None, seq_source),
            (exact, row.sequential_exact, row.sequential_enumerated, enumeration),
            (root, row.root_paper, row.root_enumerated, enumeration),
        )
        for name, formula, truth, source in against_exact:
            if truth is not None and abs(formula - truth) > AGREEMENT_TOLERANCE * max(1.0, truth):
                formulas.setdefault(name, []).append((row.m, formula, truth, source))
        against_simulation = (
            (exact, row.sequential_exact, row.sequential_simulated, row.sequential_simulated_se),
            (root, row.root_paper, row.root_simulated, row.root_simulated_se),
        )
        for name, formula, mean, se in against_simulation:
            if se > 0 and abs(formula - mean) > z * se:
                formulas.setdefault(name, []).append((row.m, formula, mean, "simulation"))
    return [_describe(name, cases) for name, cases in formulas.items()]


def _describe(name: str, cases: list[tuple[int, float, float, str]]) -> str:
    ms = ", ".join(str(m) for m, *_ in cases)
    m, formula, exact, source = cases[-1]
    relative = (formula - exact) / exact if exact else float("inf")
    return (
        f"{name} disagrees for M = {ms}; at M={m} it gives {formula:.4f} where "
        f"{source} gives {exact:.4f} ({relative:+.1%})"
    )


def compute_theory(
    ms: Sequence[int],
    sessions: int,
    enumerate_max: int,
    delta: float,
    seed: int,
    on_row: Callable[[int], None] | None = None,
) -> list[TheoryRow]:
    rng = np.random.default_rng(seed)
    recurrence = paper_sequential_recurrence(max(ms))
    rows = []
    for m in ms:
        rows.append(theory_row(m, sessions, enumerate_max, delta, rng, recurrence))
        if on_row is not None:
            on_row(m)
    return rows
