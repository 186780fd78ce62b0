"""Close a preference graph: every label that a set of answers implies by transitivity.

    python examples/close_a_graph.py

Answers are (first, second, answer) about segment ids. A cycle (0 > 1 > 2 > 0) implies
nothing about its members, so its pairs add no inferred label.
"""

from __future__ import annotations

import seqrank
from seqrank.types import AnsweredQuestion, Question

FIRST, SECOND = seqrank.Answer.FIRST, seqrank.Answer.SECOND
ANSWERS = [
    (3, 4, FIRST),
    (4, 5, FIRST),
    (5, 6, SECOND),
    (0, 1, FIRST),
    (1, 2, FIRST),
    (2, 0, FIRST),
]


def main() -> None:
    answered = [
        AnsweredQuestion(Question(k, a, b, False), answer)
        for k, (a, b, answer) in enumerate(ANSWERS)
    ]
    closed = seqrank.close_preferences(answered)
    inferred = sorted((p.first, p.second) for p in closed.pairs if p.inferred)
    print(f"{closed.stats.answered} answered, {closed.stats.inferred} inferred: {inferred}")
    print(f"{closed.stats.cyclic_components} cycle(s) over {closed.stats.cyclic_segments} segments")


if __name__ == "__main__":
    main()
