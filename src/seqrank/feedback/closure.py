"""Transitive augmentation: every pair implied by the answered preferences, flagged inferred.

One pure function serves every scheme (and a whole run, when chains span sessions):

- strict answers (FIRST / SECOND) are edges "winner is preferred to loser";
- EQUAL answers stay as 0.5 labels and are never chained (a = b, b > c does not give a > c);
- SKIP answers carry no label and no edge;
- segments on a preference cycle (a strongly connected component of two or more segments,
  which only a noisy teacher or a person can create) take part in no inferred pair, so a
  cyclic component adds nothing and no path is routed through it; their asked labels stay;
- a pair that was asked (with any non-skip answer) is never inferred again: the asked
  answer wins over the closure.

Alongside the pairs come the per-session statistics of SPEC section 3.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from seqrank.types import LABEL_FIRST, Answer, AnsweredQuestion, LabelledPair

TrueReturns = Mapping[int, float] | Sequence[float]


@dataclass(frozen=True)
class AugmentationStats:
    """Feedback accounting of one session (or any batch of answers).

    Counts of `*_wrong` are None when no ground truth was given.
    """

    asked: int
    answered: int
    equal: int
    skipped: int
    inferred: int
    asked_wrong: int | None
    inferred_wrong: int | None
    unique_segments: int
    cyclic_components: int
    cyclic_segments: int
    max_degree: int
    mean_degree: float

    @property
    def labelled(self) -> int:
        """Pairs the reward model trains on: answered plus inferred."""
        return self.answered + self.inferred

    @property
    def pairs_per_question(self) -> float:
        return self.labelled / self.asked if self.asked else 0.0

    @property
    def inferred_error_rate(self) -> float | None:
        if self.inferred_wrong is None or self.inferred == 0:
            return None
        return self.inferred_wrong / self.inferred


@dataclass(frozen=True)
class Augmentation:
    pairs: tuple[LabelledPair, ...]
    stats: AugmentationStats


def augment(
    answers: Iterable[AnsweredQuestion], true_returns: TrueReturns | None = None
) -> Augmentation:
    """Asked pairs with their labels plus every pair implied by transitivity."""
    answers = list(answers)
    asked_pairs = [
        LabelledPair(a.first, a.second, label, inferred=False)
        for a in answers
        if (label := a.answer.label) is not None
    ]
    edges = [_winner_loser(a) for a in answers if a.answer in (Answer.FIRST, Answer.SECOND)]
    components = _strongly_connected(edges)
    cyclic = [c for c in components if len(c) > 1]
    cyclic_nodes = {node for c in cyclic for node in c}
    asked_keys = {frozenset((p.first, p.second)) for p in asked_pairs}
    inferred = [
        LabelledPair(winner, loser, LABEL_FIRST, inferred=True)
        for winner, loser in _implied(edges, cyclic_nodes)
        if frozenset((winner, loser)) not in asked_keys
    ]
    pairs = tuple(asked_pairs + inferred)
    max_degree, mean_degree = dependency_degrees(pairs)
    stats = AugmentationStats(
        asked=len(answers),
        answered=len(asked_pairs),
        equal=sum(a.answer is Answer.EQUAL for a in answers),
        skipped=sum(a.answer is Answer.SKIP for a in answers),
        inferred=len(inferred),
        asked_wrong=_count_wrong(asked_pairs, true_returns),
        inferred_wrong=_count_wrong(inferred, true_returns),
        unique_segments=len({s for a in answers for s in (a.first, a.second)}),
        cyclic_components=len(cyclic),
        cyclic_segments=len(cyclic_nodes),
        max_degree=max_degree,
        mean_degree=mean_degree,
    )
    return Augmentation(pairs, stats)


def dependency_degrees(pairs: Iterable[LabelledPair]) -> tuple[int, float]:
    """Max and mean degree of the dependency graph of labelled pairs.

    Two distinct pairs are dependent when they share a segment, so the degree of pair
    {a, b} is (pairs containing a) + (pairs containing b) - 2. Repeated pairs count once.
    """
    unique = {frozenset((p.first, p.second)) for p in pairs}
    if not unique:
        return 0, 0.0
    per_segment = Counter(segment for pair in unique for segment in pair)
    degrees = [sum(per_segment[s] for s in pair) - 2 for pair in unique]
    return max(degrees), sum(degrees) / len(degrees)


def _winner_loser(answered: AnsweredQuestion) -> tuple[int, int]:
    if answered.answer is Answer.FIRST:
        return answered.first, answered.second
    return answered.second, answered.first


def _count_wrong(pairs: Sequence[LabelledPair], true_returns: TrueReturns | None) -> int | None:
    """Strict labels that contradict a strict true order (ties in truth are never wrong)."""
    if true_returns is None:
        return None
    wrong = 0
    for pair in pairs:
        if pair.label == 0.5:
            continue
        better, worse = (pair.first, pair.second) if pair.label > 0.5 else (pair.second, pair.first)
        wrong += true_returns[better] < true_returns[worse]
    return wrong


def _strongly_connected(edges: Sequence[tuple[int, int]]) -> list[list[int]]:
    """Tarjan's algorithm without recursion (long chains would overflow the stack)."""
    successors: dict[int, list[int]] = {}
    for winner, loser in edges:
        successors.setdefault(winner, []).append(loser)
        successors.setdefault(loser, [])
    index: dict[int, int] = {}
    lowlink: dict[int, int] = {}
    on_stack: set[int] = set()
    stack: list[int] = []
    components: list[list[int]] = []
    for start in successors:
        if start in index:
            continue
        work = [(start, 0)]
        while work:
            node, next_child = work.pop()
            if next_child == 0:
                index[node] = lowlink[node] = len(index)
                stack.append(node)
                on_stack.add(node)
            children = successors[node]
            if next_child < len(children):
                work.append((node, next_child + 1))
                child = children[next_child]
                if child not in index:
                    work.append((child, 0))
                elif child in on_stack:
                    lowlink[node] = min(lowlink[node], index[child])
                continue
            if work:
                parent = work[-1][0]
                lowlink[parent] = min(lowlink[parent], lowlink[node])
            if lowlink[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                components.append(component)
    return components


def _implied(edges: Sequence[tuple[int, int]], excluded: set[int]) -> list[tuple[int, int]]:
    """All (winner, loser) pairs joined by a path of edges avoiding `excluded` segments.

    Reachability sets are Python integers used as bitsets, filled in reverse topological
    order, so the cost is about (segments x segments / 64) word operations.
    """
    kept = [(w, lo) for w, lo in edges if w not in excluded and lo not in excluded]
    nodes = sorted({n for edge in kept for n in edge})
    position = {node: i for i, node in enumerate(nodes)}
    successors: list[set[int]] = [set() for _ in nodes]
    indegree = [0] * len(nodes)
    for winner, loser in kept:
        w, lo = position[winner], position[loser]
        if lo not in successors[w]:
            successors[w].add(lo)
            indegree[lo] += 1
    order = [i for i, d in enumerate(indegree) if d == 0]
    for i in order:  # Kahn's algorithm; `order` grows while we walk it
        for j in successors[i]:
            indegree[j] -= 1
            if indegree[j] == 0:
                order.append(j)
    reach = [0] * len(nodes)
    for i in reversed(order):
        bits = 0
        for j in successors[i]:
            bits |= reach[j] | (1 << j)
        reach[i] = bits
    implied = []
    for i, bits in enumerate(reach):
        while bits:
            low = bits & -bits
            implied.append((nodes[i], nodes[low.bit_length() - 1]))
            bits ^= low
    return implied
