"""Run a comparison scheme over your own `ask` function: here a person at the terminal.

    python examples/ask_in_terminal.py            # answer 1, 2, = (equal) or s (skip)
    printf '1\n2\n1\n' | python examples/ask_in_terminal.py

The five "segments" are numbers; the person says which of two they prefer. The sequential
scheme asks each new one against the previous one, and transitivity adds the pairs the
answers imply.
"""

from __future__ import annotations

import seqrank

VALUES = [3.0, 9.0, 4.0, 7.0, 1.0]  # what the person compares (stand-ins for clips)
KEYS = {"1": seqrank.Answer.FIRST, "2": seqrank.Answer.SECOND, "=": seqrank.Answer.EQUAL}


def ask(first: int, second: int) -> seqrank.Answer:
    reply = input(f"prefer 1) {VALUES[first]} or 2) {VALUES[second]}? [1/2/=/s] ").strip()
    print(reply)
    return KEYS.get(reply, seqrank.Answer.SKIP)


def main() -> None:
    record = seqrank.run_scheme("sequential", len(VALUES), budget=3, ask=ask, seed=1)
    closed = seqrank.close_preferences(record.answers, true_returns=VALUES)
    print(f"asked {closed.stats.asked}, inferred {closed.stats.inferred} more:")
    for pair in closed.pairs:
        kind = "inferred" if pair.inferred else "asked"
        print(f"  {VALUES[pair.first]} vs {VALUES[pair.second]}: label {pair.label} ({kind})")
    print(
        f"labels the values contradict: {closed.stats.asked_wrong} asked, "
        f"{closed.stats.inferred_wrong} inferred"
    )


if __name__ == "__main__":
    main()
