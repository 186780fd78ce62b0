from __future__ import annotations

import math

import numpy as np
import pytest

from seqrank.feedback.teachers import (
    TEACHER_PRESETS,
    ScriptedTeacher,
    TeacherConfig,
    teacher_preset,
)
from seqrank.types import Answer

H = 50


def constant(total: float) -> np.ndarray:
    return np.full(H, total / H)


def answers(teacher: ScriptedTeacher, a: np.ndarray, b: np.ndarray, draws: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    return [teacher.answer(a, b, rng) for _ in range(draws)]


def rate(values, target) -> float:
    return sum(v is target for v in values) / len(values)


def within_binomial(observed: float, p: float, n: int, z: float = 4.0) -> bool:
    return abs(observed - p) <= z * math.sqrt(p * (1 - p) / n)


def test_oracle_prefers_the_higher_return_either_way_round():
    oracle = ScriptedTeacher(teacher_preset("oracle"))
    rng = np.random.default_rng(0)
    assert oracle.answer(constant(10), constant(9), rng) is Answer.FIRST
    assert oracle.answer(constant(9), constant(10), rng) is Answer.SECOND


@pytest.mark.parametrize(
    ("rule", "expected"), [("equal", {Answer.EQUAL}), ("first", {Answer.FIRST})]
)
def test_exact_tie_follows_the_tie_rule(rule, expected):
    teacher = ScriptedTeacher(TeacherConfig(tie_rule=rule))
    assert set(answers(teacher, constant(5), constant(5), 50)) == expected


def test_random_tie_rule_is_a_fair_coin():
    teacher = ScriptedTeacher(TeacherConfig(tie_rule="random"))
    drawn = answers(teacher, constant(5), constant(5), 4000)
    assert set(drawn) == {Answer.FIRST, Answer.SECOND}
    assert within_binomial(rate(drawn, Answer.FIRST), 0.5, 4000)


def test_mistake_preset_flips_one_answer_in_ten():
    teacher = ScriptedTeacher(teacher_preset("mistake"))
    drawn = answers(teacher, constant(30), constant(10), 20000)
    assert within_binomial(rate(drawn, Answer.SECOND), 0.1, 20000)


def test_noisy_preset_follows_bradley_terry_with_beta_one():
    teacher = ScriptedTeacher(teacher_preset("noisy"))
    drawn = answers(teacher, constant(10.5), constant(10.0), 20000)
    expected = 1 / (1 + math.exp(-0.5))
    assert within_binomial(rate(drawn, Answer.FIRST), expected, 20000)


def test_skip_preset_skips_when_both_returns_are_at_most_eps_times_margin():
    teacher = ScriptedTeacher(teacher_preset("skip"), margin=20.0)
    rng = np.random.default_rng(0)
    assert teacher.answer(constant(2.0), constant(1.0), rng) is Answer.SKIP  # 2.0 <= 0.1 * 20
    assert teacher.answer(constant(2.1), constant(1.0), rng) is Answer.FIRST


def test_no_skip_without_eps_skip_even_for_zero_returns():
    oracle = ScriptedTeacher(teacher_preset("oracle"), margin=0.0)
    assert oracle.answer(constant(0), constant(0), np.random.default_rng(0)) is Answer.EQUAL


def test_equal_preset_marks_pairs_closer_than_eps_times_margin():
    teacher = ScriptedTeacher(teacher_preset("equal"), margin=20.0)
    rng = np.random.default_rng(0)
    assert teacher.answer(constant(11.9), constant(10.0), rng) is Answer.EQUAL  # 1.9 < 2
    assert teacher.answer(constant(12.0), constant(10.0), rng) is Answer.FIRST  # 2.0 is not < 2


def test_equal_threshold_is_linear_in_eps_never_squared():
    # eps_equal=0.1, margin=100: a gap of 5 is equal; with eps squared (0.01) it would not be.
    teacher = ScriptedTeacher(teacher_preset("equal")).with_margin(100.0).with_margin(100.0)
    assert teacher.answer(constant(25), constant(20), np.random.default_rng(0)) is Answer.EQUAL


def test_myopic_teacher_weighs_late_steps_more():
    early = np.zeros(H)
    early[:10] = 1.0  # return 10, all early
    late = np.zeros(H)
    late[-8:] = 1.0  # return 8, all late
    rng = np.random.default_rng(0)
    assert ScriptedTeacher(teacher_preset("oracle")).answer(early, late, rng) is Answer.FIRST
    assert ScriptedTeacher(teacher_preset("myopic")).answer(early, late, rng) is Answer.SECOND


def test_equal_marking_survives_mistakes_and_skip_comes_first():
    always_wrong_and_equal = ScriptedTeacher(TeacherConfig(eps_mistake=1.0, eps_equal=0.5), 10.0)
    rng = np.random.default_rng(0)
    assert always_wrong_and_equal.answer(constant(6), constant(5), rng) is Answer.EQUAL
    assert always_wrong_and_equal.answer(constant(16), constant(5), rng) is Answer.SECOND
    skip_and_equal = ScriptedTeacher(TeacherConfig(eps_skip=0.5, eps_equal=0.5), 10.0)
    assert skip_and_equal.answer(constant(5), constant(4.9), rng) is Answer.SKIP


def test_presets_are_the_six_b_pref_teachers():
    assert list(TEACHER_PRESETS) == ["oracle", "mistake", "noisy", "skip", "myopic", "equal"]
    assert teacher_preset("noisy").beta == 1.0 and teacher_preset("myopic").gamma == 0.9
    assert teacher_preset("oracle").deterministic and not teacher_preset("noisy").deterministic


def test_unknown_preset_names_the_accepted_ones():
    with pytest.raises(ValueError, match="unknown teacher preset 'perfect'; accepted: oracle"):
        teacher_preset("perfect")


@pytest.mark.parametrize(
    ("field", "value"), [("gamma", 0.0), ("gamma", 1.5), ("eps_mistake", -0.1), ("eps_skip", 2.0)]
)
def test_bad_knob_values_are_rejected_by_name(field, value):
    with pytest.raises(ValueError, match=field):
        TeacherConfig(**{field: value})
