from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from seqrank.theory import (
    compute_theory,
    disagreements,
    enumerate_orderings,
    exact_sequential_linear,
    exact_sequential_pairs,
    paper_sequential_linear,
    paper_sequential_recurrence,
    root_degree_bound,
    root_pairs,
    sequential_degree_bound,
    simulate_orderings,
)


def test_hand_worked_small_cases():
    # M=3: the 2 monotone orderings label all 3 pairs, the other 4 label 2.
    assert enumerate_orderings("sequential", 3).pairs == pytest.approx(14 / 6)
    # M=4 sequential: 3 adjacent + 2 * P(3 monotone)=1/3 + P(4 monotone)=1/12 = 15/4
    assert enumerate_orderings("sequential", 4).pairs == pytest.approx(15 / 4)
    # M=3 root: the last challenger wins w.p. 1/3 (2 pairs) else 1 pair, plus 1 for question 1
    assert enumerate_orderings("root", 3).pairs == pytest.approx(1 + (1 / 3) * 2 + (2 / 3) * 1)


@pytest.mark.parametrize("m", range(2, 8))
def test_exact_sequential_formula_equals_enumeration(m):
    assert exact_sequential_pairs(m) == pytest.approx(enumerate_orderings("sequential", m).pairs)


@pytest.mark.parametrize("m", range(2, 8))
def test_root_formula_equals_enumeration(m):
    assert root_pairs(m) == pytest.approx(enumerate_orderings("root", m).pairs)


def test_paper_recurrence_matches_up_to_three_then_undercounts():
    recurrence = paper_sequential_recurrence(8)
    assert recurrence[2] == pytest.approx(1) and recurrence[3] == pytest.approx(7 / 3)
    # Lemma 1 at M=4: 2 - 2/24 + a_3 * 4/6 + a_2 * 6/24, computed exactly
    paper_a4 = Fraction(2) - Fraction(2, 24) + Fraction(7, 3) * Fraction(4, 6) + Fraction(6, 24)
    assert recurrence[4] == pytest.approx(float(paper_a4))
    assert float(paper_a4) < enumerate_orderings("sequential", 4).pairs


def test_exact_formula_approaches_its_asymptote():
    assert abs(exact_sequential_pairs(101) - exact_sequential_linear(101)) < 1e-12
    assert 2 * (math.e - 2) == pytest.approx(1.43656, abs=1e-5)
    assert paper_sequential_linear(101) == pytest.approx(38.75 + 100, abs=0.01)


def test_degree_bounds_reproduce_the_papers_numbers():
    assert sequential_degree_bound(101, 0.03) == pytest.approx(10.11, abs=0.005)
    assert root_degree_bound(101, 0.03) == pytest.approx(195.97)
    assert root_pairs(101) - 100 == pytest.approx(91.61, abs=0.005)


@pytest.mark.parametrize(("scheme", "m"), [("sequential", 11), ("root", 11), ("sequential", 101)])
def test_simulation_of_the_real_code_is_within_a_few_standard_errors(scheme, m):
    sim = simulate_orderings(scheme, m, 1500, np.random.default_rng(7))
    exact = exact_sequential_pairs(m) if scheme == "sequential" else root_pairs(m)
    assert abs(sim.pairs - exact) < 4 * sim.pairs_se
    assert sim.pairs_se > 0


def test_enumerated_max_degree_of_small_sessions():
    # M=3 sequential: monotone orderings give a triangle (degree 2), others 2 pairs sharing
    # one segment (degree 1): (2*2 + 4*1)/6
    assert enumerate_orderings("sequential", 3).max_degree == pytest.approx(8 / 6)


def test_findings_name_the_paper_recurrence_and_clear_the_exact_formulas():
    rows = compute_theory([3, 4, 5, 11], sessions=300, enumerate_max=5, delta=0.03, seed=1)
    findings = disagreements(rows)
    assert any(
        f.startswith("paper recurrence a_M (Lemma 1) disagrees for M = 4, 5, 11") for f in findings
    )
    assert not any("exact sequential formula" in f or "root b_M" in f for f in findings)
    assert rows[0].sequential_enumerated is not None and rows[-1].sequential_enumerated is None
