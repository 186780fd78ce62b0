from __future__ import annotations

import itertools

from hypothesis import given, settings
from hypothesis import strategies as st

from seqrank.feedback.closure import augment, dependency_degrees
from seqrank.types import Answer, AnsweredQuestion, LabelledPair, Question

F, S, E, K = Answer.FIRST, Answer.SECOND, Answer.EQUAL, Answer.SKIP


def answered(*triples: tuple[int, int, Answer]) -> list[AnsweredQuestion]:
    return [AnsweredQuestion(Question(i, a, b, True), ans) for i, (a, b, ans) in enumerate(triples)]


def inferred_of(result) -> set[tuple[int, int]]:
    return {(p.first, p.second) for p in result.pairs if p.inferred}


def test_chain_is_closed_and_inferred_pairs_are_flagged():
    result = augment(answered((0, 1, F), (2, 1, S), (2, 3, F)))  # 0 > 1 > 2 > 3
    assert inferred_of(result) == {(0, 2), (0, 3), (1, 3)}
    assert all(p.label == 1.0 for p in result.pairs if p.inferred)
    assert result.stats.asked == 3 and result.stats.inferred == 3 and result.stats.labelled == 6


def test_ties_are_labelled_half_and_never_chained():
    result = augment(answered((0, 1, E), (1, 2, F), (3, 0, F)))
    assert inferred_of(result) == set()
    assert LabelledPair(0, 1, 0.5, inferred=False) in result.pairs
    assert result.stats.equal == 1


def test_skips_carry_no_label_and_no_edge():
    result = augment(answered((0, 1, F), (1, 2, K), (2, 3, F)))
    assert result.stats.answered == 2 and result.stats.skipped == 1
    assert inferred_of(result) == set() and len(result.pairs) == 2


def test_a_cycle_adds_no_inferred_pair_and_blocks_paths_through_it():
    # 0 > 1 > 2 > 0 is a cycle; 3 > 0 and 2 > 4 would imply 3 > 4 only through the cycle.
    # 5 > 6 > 7 is clean and still closes.
    result = augment(
        answered((0, 1, F), (1, 2, F), (2, 0, F), (3, 0, F), (2, 4, F), (5, 6, F), (6, 7, F))
    )
    assert inferred_of(result) == {(5, 7)}
    assert result.stats.cyclic_components == 1 and result.stats.cyclic_segments == 3
    assert result.stats.answered == 7  # asked labels stay


def test_conflicting_answers_to_one_pair_cancel_out_and_their_labels_stay():
    result = augment(answered((0, 1, F), (0, 1, S), (1, 2, F)))
    assert result.stats.cyclic_components == 0 and inferred_of(result) == set()
    assert result.stats.answered == 3 and result.stats.answered_pairs == 2


def test_a_repeated_pair_takes_the_direction_of_most_answers():
    # 0 > 1 twice, once 1 > 0 (asked from the other side): 0 > 1 stands, and 0 > 2 follows
    result = augment(answered((0, 1, F), (1, 0, F), (0, 1, F), (1, 2, F)))
    assert inferred_of(result) == {(0, 2)}
    assert result.stats.pairs_per_question == 3 / 4  # distinct pairs per question


def test_noise_aware_closure_counts_unconfirmed_edges_on_a_path():
    # 0 > 1 confirmed (asked twice, same answer), 1 > 2 and 2 > 3 asked once each
    answers = answered((0, 1, F), (0, 1, F), (1, 2, F), (2, 3, F))
    assert inferred_of(augment(answers)) == {(0, 2), (0, 3), (1, 3)}
    assert inferred_of(augment(answers, path_unchecked=1)) == {(0, 2)}
    assert inferred_of(augment(answers, path_unchecked=0)) == set()


def test_a_vouched_answer_counts_as_confirmed_and_only_in_its_direction():
    # as above; the reward model agreed with 1 > 2, so a path may use it as confirmed
    answers = answered((0, 1, F), (0, 1, F), (1, 2, F), (2, 3, F))
    vouched = augment(answers, path_unchecked=1, vouched={(1, 2)})
    assert inferred_of(vouched) == {(0, 2), (0, 3), (1, 3)}
    assert inferred_of(augment(answers, path_unchecked=0, vouched={(1, 2)})) == {(0, 2)}
    # an edge vouched the other way round (the model disagreed) is not confirmed
    assert inferred_of(augment(answers, path_unchecked=0, vouched={(2, 1)})) == set()
    # a pair whose answers disagree stays without an edge, vouched or not
    split = answered((0, 1, F), (0, 1, F), (1, 2, F), (1, 2, S))
    assert inferred_of(augment(split, path_unchecked=5, vouched={(1, 2)})) == set()


def test_noise_aware_closure_never_infers_through_a_contradicted_pair():
    # 1 vs 2 answered both ways: no edge, so 0 > 1 and 2 > 3 (both confirmed) imply nothing
    # across it; with a third answer 1 > 2 the edge stands but is unconfirmed
    base = [(0, 1, F), (0, 1, F), (2, 3, F), (2, 3, F)]
    contradicted = answered(*base, (1, 2, F), (1, 2, S))
    assert inferred_of(augment(contradicted, path_unchecked=5)) == set()
    outvoted = answered(*base, (1, 2, F), (1, 2, S), (1, 2, F))
    assert inferred_of(augment(outvoted, path_unchecked=0)) == set()
    assert inferred_of(augment(outvoted, path_unchecked=1)) == {(0, 2), (0, 3), (1, 3)}


def test_asked_pairs_are_not_inferred_again_even_when_answered_equal():
    result = augment(answered((0, 1, F), (1, 2, F), (0, 2, E)))
    assert inferred_of(result) == set()
    assert LabelledPair(0, 2, 0.5, inferred=False) in result.pairs


def test_wrong_counts_use_ground_truth_and_ties_in_truth_are_never_wrong():
    truth = [1.0, 3.0, 2.0, 2.0]
    # asked: 0 > 1 wrong; 1 > 2 right; 2 > 3 a truth tie (not wrong); inferred 0 > 2 wrong,
    # 0 > 3 wrong, 1 > 3 right
    result = augment(answered((0, 1, F), (1, 2, F), (2, 3, F)), truth)
    assert result.stats.asked_wrong == 1
    assert result.stats.inferred_wrong == 2 and result.stats.inferred == 3
    assert result.stats.inferred_error_rate == 2 / 3
    assert augment(answered((0, 1, F))).stats.inferred_wrong is None


def test_dependency_degree_of_a_hand_worked_graph():
    # pairs {0,1}, {1,2}, {0,2}, {3,4}: each of the triangle shares a segment with the other
    # two (degree 2), {3,4} with none.
    pairs = [
        LabelledPair(0, 1, 1, False),
        LabelledPair(1, 2, 1, False),
        LabelledPair(0, 2, 1, True),
        LabelledPair(3, 4, 0.5, False),
        LabelledPair(1, 0, 0, False),
    ]  # a repeat of {0,1}, counted once
    assert dependency_degrees(pairs) == (2, 1.5)
    assert dependency_degrees([]) == (0, 0.0)


def test_a_long_cycle_needs_no_recursion():
    n = 5000  # a depth-first search this deep would overflow Python's recursion limit
    result = augment(answered(*[(i, (i + 1) % n, F) for i in range(n)]))
    assert result.stats.cyclic_components == 1 and result.stats.cyclic_segments == n
    assert result.stats.inferred == 0


def test_a_chain_closes_completely():
    n = 300
    result = augment(answered(*[(i, i + 1, F) for i in range(n)]))
    assert result.stats.inferred == (n + 1) * n // 2 - n


def reference_closure(answers: list[AnsweredQuestion]) -> set[tuple[int, int]]:
    """Floyd-Warshall on the pairs' majority edges, minus cyclic nodes, minus asked pairs."""
    nodes = sorted({s for a in answers for s in (a.first, a.second)})
    edges = {edge for edge, _ in majority_edges(answers)}

    def reach(allowed):
        r = {(u, v) for u, v in edges if u in allowed and v in allowed}
        for k, i, j in itertools.product(allowed, allowed, allowed):
            if (i, k) in r and (k, j) in r:
                r.add((i, j))
        return r

    full = reach(nodes)
    cyclic = {u for u in nodes if any((u, v) in full and (v, u) in full for v in nodes)}
    clean = reach([n for n in nodes if n not in cyclic])
    asked = {frozenset((a.first, a.second)) for a in answers if a.answer is not K}
    return {(u, v) for u, v in clean if u != v and frozenset((u, v)) not in asked}


def majority_edges(answers: list[AnsweredQuestion]) -> list[tuple[tuple[int, int], bool]]:
    """(winner, loser) per answered pair by its answers' mean label, and whether every
    answer agreed and there were two or more."""
    labels: dict[frozenset[int], list[tuple[int, int, float]]] = {}
    for a in answers:
        if a.answer.label is not None:
            labels.setdefault(frozenset((a.first, a.second)), []).append(
                (a.first, a.second, a.answer.label)
            )
    edges = []
    for pair_labels in labels.values():
        a, b, _ = pair_labels[0]
        oriented = [label if first == a else 1 - label for first, _, label in pair_labels]
        mean = sum(oriented) / len(oriented)
        if mean != 0.5:
            agreed = len(oriented) > 1 and len(set(oriented)) == 1
            edges.append(((a, b) if mean > 0.5 else (b, a), agreed))
    return edges


def reference_trusted_closure(answers: list[AnsweredQuestion], k: int) -> set[tuple[int, int]]:
    """Bellman-Ford on the fewest unconfirmed edges from each node, cyclic nodes removed."""
    nodes = {s for a in answers for s in (a.first, a.second)}
    full = {e for e, _ in majority_edges(answers)}
    for k_, i, j in itertools.product(nodes, nodes, nodes):
        if (i, k_) in full and (k_, j) in full:
            full.add((i, j))
    cyclic = {u for u in nodes if any((u, v) in full and (v, u) in full for v in nodes)}
    edges = [(e, c) for e, c in majority_edges(answers) if not set(e) & cyclic]
    asked = {frozenset((a.first, a.second)) for a in answers if a.answer is not K}
    found = set()
    for start in nodes - cyclic:
        cost = {start: 0}
        for _ in nodes:
            for (u, v), agreed in edges:
                if u in cost and cost[u] + (not agreed) < cost.get(v, 10**9):
                    cost[v] = cost[u] + (not agreed)
        found |= {(start, v) for v, c in cost.items() if v != start and c <= k}
    return {p for p in found if frozenset(p) not in asked}


graph_answers = st.lists(
    st.tuples(st.integers(0, 7), st.integers(0, 7), st.sampled_from([F, S, E, K])).filter(
        lambda t: t[0] != t[1]
    ),
    max_size=20,
)


@settings(max_examples=300, deadline=None)
@given(triples=graph_answers)
def test_closure_matches_a_brute_force_reference_on_any_graph(triples):
    answers = answered(*triples)
    assert inferred_of(augment(answers)) == reference_closure(answers)


@settings(max_examples=300, deadline=None)
@given(triples=graph_answers, k=st.integers(0, 3))
def test_noise_aware_closure_matches_a_brute_force_reference(triples, k):
    answers = answered(*triples, *triples[: len(triples) // 2])  # some pairs asked twice
    assert inferred_of(augment(answers, path_unchecked=k)) == reference_trusted_closure(answers, k)


@settings(max_examples=100, deadline=None)
@given(triples=graph_answers)
def test_closing_a_closed_set_adds_nothing(triples):
    once = augment(answered(*triples))
    closed = [(p.first, p.second, F) for p in once.pairs if p.label == 1.0]
    closed += [(p.first, p.second, S) for p in once.pairs if p.label == 0.0]
    closed += [(p.first, p.second, E) for p in once.pairs if p.label == 0.5]
    if once.stats.cyclic_components == 0:
        assert augment(answered(*closed)).stats.inferred == 0
