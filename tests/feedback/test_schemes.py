from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from seqrank.feedback.closure import augment
from seqrank.feedback.schemes import (
    SCHEMES,
    get_scheme,
    in_order_choice,
    pairwise,
    ranked,
    root,
    segments_needed,
    sequential,
    uniform_choice,
)
from seqrank.types import Answer
from support.asks import perfect_ask, rng


def asked_pairs(record):
    return [(a.first, a.second) for a in record.answers]


def labelled(record, values):
    result = augment(record.answers, values)
    return {(p.first, p.second, p.label, p.inferred) for p in result.pairs}, result.stats


def test_pairwise_asks_n_disjoint_pairs_of_2n_distinct_segments():
    values = list(range(30))
    record = pairwise(30, 10, perfect_ask(values), rng())
    segments = [s for pair in asked_pairs(record) for s in pair]
    assert record.asked == 10 and len(set(segments)) == 20
    assert all(not a.question.first_is_defender for a in record.answers)
    assert augment(record.answers, values).stats.inferred == 0


def test_sequential_hand_worked_example():
    values = [3, 1, 2, 5, 4]
    record = sequential(5, 4, perfect_ask(values), rng(), in_order_choice)
    assert asked_pairs(record) == [(0, 1), (1, 2), (2, 3), (3, 4)]
    assert [a.answer for a in record.answers] == [
        Answer.FIRST,
        Answer.SECOND,
        Answer.SECOND,
        Answer.FIRST,
    ]
    pairs, stats = labelled(record, values)
    assert {(f, s) for f, s, _, inferred in pairs if inferred} == {(3, 1)}
    assert stats.labelled == 5 and stats.unique_segments == 5


def test_root_hand_worked_example():
    values = [2, 5, 1, 7, 3]
    record = root(5, 4, perfect_ask(values), rng(), in_order_choice)
    # roots: 0, then 1 wins, 2 loses to 1, 3 wins, 4 loses to 3
    assert asked_pairs(record) == [(0, 1), (1, 2), (1, 3), (3, 4)]
    assert all(a.question.first_is_defender for a in record.answers)
    pairs, stats = labelled(record, values)
    assert {(f, s) for f, s, _, inferred in pairs if inferred} == {(3, 0), (3, 2)}
    assert stats.labelled == 6


def test_ranked_hand_worked_example_orders_everything():
    values = [5, 3, 8, 4]
    record = ranked(4, 10, perfect_ask(values), rng(), in_order_choice)
    assert asked_pairs(record) == [(0, 1), (0, 2), (0, 3), (1, 3)]
    pairs, stats = labelled(record, values)
    assert {(f, s) for f, s, _, inferred in pairs if inferred} == {(2, 1), (2, 3)}
    assert stats.labelled == 6  # a total order of 4 segments


def test_ranked_budget_caps_questions_mid_insertion():
    record = ranked(4, 3, perfect_ask([5, 3, 8, 4]), rng(), in_order_choice)
    assert record.asked == 3
    assert record.segments == (0, 1, 2, 3)  # the last segment was drawn but not placed


def test_ranked_equal_answer_joins_the_group_and_is_not_chained():
    values = [5, 5, 1]
    record = ranked(3, 10, perfect_ask(values), rng(), in_order_choice)
    # 1 ties with founder 0 and joins its group; 2 is compared with founder 0 only
    assert asked_pairs(record) == [(0, 1), (0, 2)]
    pairs, stats = labelled(record, values)
    assert stats.equal == 1 and stats.inferred == 0
    assert (0, 1, 0.5, False) in pairs


def test_sequential_equal_and_skip_break_the_chain_but_move_on():
    script = {
        (0, 1): Answer.FIRST,
        (1, 2): Answer.EQUAL,
        (2, 3): Answer.FIRST,
        (3, 4): Answer.SKIP,
        (4, 5): Answer.FIRST,
    }
    record = sequential(6, 5, lambda a, b: script[(a, b)], rng(), in_order_choice)
    stats = augment(record.answers).stats
    assert asked_pairs(record) == list(script)
    assert stats.inferred == 0 and stats.answered == 4 and stats.skipped == 1


def test_root_keeps_its_root_on_equal_and_skip():
    script = {
        (0, 1): Answer.EQUAL,
        (0, 2): Answer.SKIP,
        (0, 3): Answer.SECOND,
        (3, 4): Answer.FIRST,
    }
    record = root(5, 4, lambda a, b: script[(a, b)], rng(), in_order_choice)
    assert asked_pairs(record) == list(script)
    pairs = {(p.first, p.second) for p in augment(record.answers).pairs if p.inferred}
    assert pairs == set()  # 3 > 0 and 3 > 4 only; the tie with 1 is not chained


def test_challengers_are_never_drawn_twice():
    for name, scheme in SCHEMES.items():
        record = scheme(
            200, 60, perfect_ask(np.random.default_rng(1).random(200)), rng(), uniform_choice
        )
        assert len(set(record.segments)) == len(record.segments), name


@pytest.mark.parametrize("name", list(SCHEMES))
def test_too_small_a_pool_is_a_clear_error(name):
    with pytest.raises(ValueError, match="distinct segments, but the pool has 1"):
        get_scheme(name)(1, 3, perfect_ask([1.0]), rng(), in_order_choice)


def test_unknown_scheme_names_the_accepted_ones():
    with pytest.raises(ValueError, match="unknown scheme 'rooted'; accepted: pairwise"):
        get_scheme("rooted")


def test_segments_needed():
    assert segments_needed("pairwise", 10) == 20
    assert segments_needed("sequential", 10) == 11
    assert segments_needed("root", 10) == 11


distinct_values = st.lists(st.integers(-1000, 1000), min_size=2, max_size=40, unique=True)


@settings(max_examples=150, deadline=None)
@given(values=distinct_values, data=st.data(), scheme=st.sampled_from(list(SCHEMES)))
def test_perfect_teacher_inferred_pairs_always_agree_with_the_true_order(values, data, scheme):
    pool = len(values)
    max_budget = pool // 2 if scheme == "pairwise" else pool - 1
    budget = data.draw(st.integers(1, max_budget))
    seed = data.draw(st.integers(0, 2**32 - 1))
    record = get_scheme(scheme)(pool, budget, perfect_ask(values), rng(seed), uniform_choice)
    result = augment(record.answers, values)
    assert result.stats.inferred_wrong == 0 and result.stats.asked_wrong == 0
    assert all(values[p.first] > values[p.second] for p in result.pairs if p.inferred)
    assert record.asked == budget or (
        scheme == "ranked" and not set(range(pool)) - set(record.segments)
    )
