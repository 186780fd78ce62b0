"""Augmented pairs per session on a reward-benchmark grid, against theory and the paper.

Issue 46, item 2 (segment order): a session of N questions on M = N + 1 segments in a
random order is expected to add `seqrank theory`'s augmented pairs; the paper's D.6 counts
640.29 for root (and 46.00 for sequential) at window-open's first reward update, 7x (1.19x)
theory's expectation. This prints, for each scheme and order of a grid, the mean augmented
pairs of each session over seeds with a 95% t-interval, beside theory's expectation.

    python scripts/augmented_per_session.py GRID_FOLDER [GRID_FOLDER ...]
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

from seqrank.report.stats import interval
from seqrank.theory import exact_sequential_pairs, root_pairs

# Supplementary D.6 (window-open, 100 questions a session): the first reward update's
# augmented pairs and the random-order expectation the paper sets beside them.
PAPER_FIRST_SESSION = {"sequential": (46.00, 38.75), "root": (640.29, 91.61)}
EXPECTED_PAIRS = {"sequential": exact_sequential_pairs, "root": root_pairs}


def expected_augmented(scheme: str, questions: int) -> float:
    """Theory's expected inferred pairs of a session of `questions` on a random order."""
    return EXPECTED_PAIRS[scheme](questions + 1) - questions


def last_rows(rows_file: Path) -> dict[tuple[str, str, str], list[list[int]]]:
    """Each (task, scheme, order)'s per-session counts, from each seed's largest budget."""
    longest: dict[tuple[str, str, str, int], dict] = {}
    for line in rows_file.read_text().splitlines():
        row = json.loads(line)
        if row["scheme"] not in EXPECTED_PAIRS:
            continue
        key = (row["task"], row["scheme"], row.get("order", "uniform"), row["seed"])
        if key not in longest or row["questions"] > longest[key]["questions"]:
            longest[key] = row
    grouped: dict[tuple[str, str, str], list[list[int]]] = defaultdict(list)
    for (task, scheme, order, _), row in sorted(longest.items()):
        grouped[(task, scheme, order)].append(row["session_inferred"])
    return grouped


def table(grid: Path) -> list[str]:
    questions = json.loads((grid / "settings.json").read_text())["session_questions"]
    lines = [
        f"### {grid.name} ({questions} questions a session)",
        "",
        "| task | scheme | order | session | seeds | augmented pairs [95% CI] "
        "| theory (random order) | ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for (task, scheme, order), sessions in last_rows(grid / "rows.jsonl").items():
        expected = expected_augmented(scheme, questions)
        for index in range(max(len(counts) for counts in sessions)):
            values = [counts[index] for counts in sessions if len(counts) > index]
            mean, low, high = interval([float(v) for v in values])
            lines.append(
                f"| {task} | {scheme} | {order} | {index + 1} | {len(values)} "
                f"| {mean:.1f} [{low:.1f}, {high:.1f}] | {expected:.1f} "
                f"| {mean / expected:.2f} |"
            )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("grids", nargs="+", type=Path, help="reward-bench run --out folders")
    args = parser.parse_args()
    for grid in args.grids:
        print("\n".join(table(grid)), end="\n\n")
    paper = ", ".join(
        f"{scheme} {count:.2f} against {expected:.2f} expected"
        for scheme, (count, expected) in PAPER_FIRST_SESSION.items()
    )
    print(f"Paper, supplementary D.6 (window-open, first session of 100 questions): {paper}.")


if __name__ == "__main__":
    main()
