"""Transitive augmentation: every pair implied by the answered preferences, flagged inferred.

One pure function serves every scheme (and a whole run, when chains span sessions):

- strict answers (FIRST / SECOND) are edges "winner is preferred to loser";
- EQUAL answers stay as 0.5 labels and are never chained (a = b, b > c does not give a > c);
- SKIP answers carry no label and no edge;
- segments on a preference cycle (a strongly connected component of two or more segments,
  which only a noisy teacher or a person can create) take part in no inferred pair, so a
  cyclic component adds nothing and no path is routed through it; their asked labels stay;
- a pair that was asked (with any non-skip answer) is never inferred again: the asked
  answer wins over the closure;
- a pair asked more than once (a re-check) is one edge, in the direction of the mean of its
  answers' labels (none when they cancel out); each answer stays its own training label.
  The edge is *confirmed* when two or more answers agree and none disagrees.

With `path_unchecked=k` (noise-aware augmentation, `augment checked`) a pair is inferred
only along a path with at most k unconfirmed edges; None (the paper's closure) trusts every
edge. One wrong answer then implies wrong pairs only through confirmed edges, which a noisy
teacher rarely gets wrong twice. An answer the fitted reward model agreed with, of a teacher
who has never contradicted themselves, is confirmed too (`vouched`; it was not asked again).

Alongside the pairs come the per-session statistics of SPEC section 3.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Collection, Iterable, Mapping, Sequence
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
    answered_pairs: int  # distinct pairs among the answered (re-checks ask a pair again)
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
        """Distinct labelled pairs (asked or inferred) per question asked."""
        return (self.answered_pairs + self.inferred) / self.asked if self.asked else 0.0

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
    answers: Iterable[AnsweredQuestion],
    true_returns: TrueReturns | None = None,
    path_unchecked: int | None = None,
    vouched: Collection[tuple[int, int]] = frozenset(),
    closure: bool = True,
) -> Augmentation:
    """Asked pairs with their labels plus every pair implied by transitivity (along paths
    of at most `path_unchecked` unconfirmed edges, when given). `vouched` winner-loser
    edges count as confirmed on one answer (the reward model agreed with it). With
    `closure` False nothing is inferred: the asked pairs alone (the reward benchmark's
    `--augments none`, which separates what the inferred labels add)."""
    answers = list(answers)
    asked_pairs = [
        LabelledPair(a.first, a.second, label, inferred=False)
        for a in answers
        if (label := a.answer.label) is not None
    ]
    votes = _votes(answers)
    confirmed, single = _majority_edges(votes, vouched)
    components = _strongly_connected(confirmed + single)
    cyclic = [c for c in components if len(c) > 1]
    cyclic_nodes = {node for c in cyclic for node in c}
    if not closure:
        implied = []
    elif path_unchecked is None:
        implied = _implied(confirmed + single, cyclic_nodes)
    else:
        implied = _implied_trusted(confirmed, single, cyclic_nodes, path_unchecked)
    inferred = [
        LabelledPair(winner, loser, LABEL_FIRST, inferred=True)
        for winner, loser in implied
        if _key(winner, loser) not in votes
    ]
    pairs = tuple(asked_pairs + inferred)
    max_degree, mean_degree = dependency_degrees(pairs)
    stats = AugmentationStats(
        asked=len(answers),
        answered=len(asked_pairs),
        answered_pairs=len(votes),
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


def _key(a: int, b: int) -> tuple[int, int]:
    return (a, b) if a < b else (b, a)


def _votes(answers: Sequence[AnsweredQuestion]) -> dict[tuple[int, int], list[float]]:
    """Each answered pair's labels, oriented to its smaller segment id first."""
    votes: dict[tuple[int, int], list[float]] = {}
    for a in answers:
        label = a.answer.label
        if label is None:
            continue
        key = _key(a.first, a.second)
        votes.setdefault(key, []).append(label if a.first == key[0] else 1.0 - label)
    return votes


Edges = list[tuple[int, int]]


def _majority_edges(
    votes: Mapping[tuple[int, int], list[float]], vouched: Collection[tuple[int, int]]
) -> tuple[Edges, Edges]:
    """(confirmed, unconfirmed) winner-loser edges: one per pair whose mean label is not
    1/2; confirmed when two or more answers agree and none disagrees, or on one vouched
    answer."""
    confirmed: Edges = []
    single: Edges = []
    for (a, b), labels in votes.items():
        mean = sum(labels) / len(labels)
        if mean == 0.5:
            continue
        edge = (a, b) if mean > 0.5 else (b, a)
        unanimous = len(labels) > 1 and len(set(labels)) == 1
        sure = unanimous or (len(labels) == 1 and edge in vouched)
        (confirmed if sure else single).append(edge)
    return confirmed, single


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
    """All (winner, loser) pairs joined by a path of edges avoiding `excluded` segments."""
    kept = [(w, lo) for w, lo in edges if w not in excluded and lo not in excluded]
    nodes = sorted({n for edge in kept for n in edge})
    return _listed(nodes, _reach(nodes, kept))


def _implied_trusted(
    confirmed: Edges, single: Edges, excluded: set[int], path_unchecked: int
) -> list[tuple[int, int]]:
    """Pairs joined by a path with at most `path_unchecked` unconfirmed edges.

    With C the confirmed reachability (reflexive) and S one unconfirmed edge, the pairs
    reachable with k unconfirmed edges are C (S C)^k: a level's set grows by one
    S-then-C step from each of its members, `path_unchecked` times.
    """
    confirmed = [(w, lo) for w, lo in confirmed if w not in excluded and lo not in excluded]
    single = [(w, lo) for w, lo in single if w not in excluded and lo not in excluded]
    nodes = sorted({n for edge in confirmed + single for n in edge})
    position = {node: i for i, node in enumerate(nodes)}
    closed = [bits | (1 << i) for i, bits in enumerate(_reach(nodes, confirmed))]
    after_single = [0] * len(nodes)  # one unconfirmed edge, then confirmed ones
    for winner, loser in single:
        after_single[position[winner]] |= closed[position[loser]]
    reach = []
    for i in range(len(nodes)):
        level = closed[i]
        for _ in range(path_unchecked):
            grown = level
            for j in _members(level):
                grown |= after_single[j]
            if grown == level:
                break
            level = grown
        reach.append(level & ~(1 << i))
    return _listed(nodes, reach)


def _members(bits: int) -> list[int]:
    found = []
    while bits:
        low = bits & -bits
        found.append(low.bit_length() - 1)
        bits ^= low
    return found


def _listed(nodes: Sequence[int], reach: Sequence[int]) -> list[tuple[int, int]]:
    return [(nodes[i], nodes[j]) for i, bits in enumerate(reach) for j in _members(bits)]


def _reach(nodes: Sequence[int], edges: Sequence[tuple[int, int]]) -> list[int]:
    """Per node (by position in `nodes`), the bitset of nodes reachable along `edges`
    (which must form no cycle).

    Reachability sets are Python integers used as bitsets, filled in reverse topological
    order, so the cost is about (segments x segments / 64) word operations.
    """
    position = {node: i for i, node in enumerate(nodes)}
    successors: list[set[int]] = [set() for _ in nodes]
    indegree = [0] * len(nodes)
    for winner, loser in edges:
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
    return reach
