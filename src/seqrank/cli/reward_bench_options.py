"""`seqrank reward-bench run`'s options: the grid's axes (how the answers are learnt from,
the order segments come in) and its sizes (budgets, sessions, windows, epochs, workers,
folder)."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from seqrank.choices import CrowdWeighting, RewardLearner
from seqrank.cli.options import int_between, names, positive
from seqrank.rewardbench.cells import AUGMENTS, ORDERS, STOPS

LEARNERS = [learner.value for learner in RewardLearner]


def budgets(text: str) -> list[int]:
    try:
        values = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give whole numbers, comma-separated") from None
    if not values or values[0] < 1 or values != sorted(set(values)):
        raise argparse.ArgumentTypeError(
            f"{text!r}: give question counts of at least 1 that rise strictly, e.g. 25,50,100"
        )
    return values


def add_grid_axes(grid: argparse.ArgumentParser) -> None:
    """The ways of learning from the answers and the order segments come in: axes."""
    grid.add_argument(
        "--learners",
        type=names(LEARNERS, "learner"),
        default=["plain"],
        help="reward learners, comma-separated (plain); RIME's warm start needs a "
        "pre-training phase, which the benchmark has not",
    )
    grid.add_argument(
        "--augments",
        type=names(AUGMENTS, "augmentation"),
        default=["full"],
        help="full (the paper's closure), checked (noise-aware augmentation), none (no "
        "closure: the asked pairs alone), comma-separated (full)",
    )
    grid.add_argument(
        "--stops",
        type=names(STOPS, "stop rule"),
        default=["all"],
        help="what the reward fit's early stop counts its train accuracy over: all (every "
        "label, asked and inferred, as a run does), asked (the asked pairs only), never (no "
        "early stop: every one of --reward-epochs), comma-separated (all)",
    )
    grid.add_argument(
        "--orders",
        type=names(ORDERS, "order"),
        default=["uniform"],
        help="how a session's new segments come: uniform (drawn uniformly from the training "
        "episodes, as a run draws them), collection (the same segments in the order the "
        "episodes were collected), comma-separated (uniform)",
    )
    grid.add_argument(
        "--weightings",
        type=names([w.value for w in CrowdWeighting], "weighting"),
        default=["none"],
        help="a crowd teacher's labels: reliability (each the probability that its member "
        "is right), drop (a flagged member's labels left out), reask (as drop, and a "
        "flagged member's questions asked again of someone else in place of the overlap's "
        "opinions), none (as answered), "
        "comma-separated (none)",
    )


def add_crowd_evidence(grid: argparse.ArgumentParser) -> None:
    """How a crowd teacher gathers evidence of its members' reliability."""
    grid.add_argument(
        "--overlap-until",
        type=int_between(0, 10_000),
        default=0,
        metavar="N",
        help="a crowd teacher's adaptive overlap: every answer of a member with fewer than N "
        "answers shared with another member is asked again of someone else (0: a share 0.1 "
        "of the answers only)",
    )
    grid.add_argument(
        "--closure-checks",
        type=int_between(0, 1),
        default=0,
        help="a crowd teacher: 1 asks each second opinion, where the owner's chain inferred "
        "one, on a pair its closure inferred (one answer checks several of theirs); 0: on the "
        "asked pair (0)",
    )


def add_grid_sizes(grid: argparse.ArgumentParser) -> None:
    """How much each cell asks and trains, and where the grid runs and writes."""
    grid.add_argument(
        "--budgets",
        type=budgets,
        default=[25, 50, 100, 200],
        help="question counts at which the reward model is trained and measured (25,50,100,200)",
    )
    grid.add_argument(
        "--session-questions", type=positive, default=25, help="questions per session (25)"
    )
    grid.add_argument(
        "--segment-length",
        type=int_between(1, 100_000),
        default=50,
        help="steps per compared segment, at most a pool's longest episode (50; LiRE's "
        "offline setting: 25)",
    )
    grid.add_argument(
        "--heldout-segments",
        type=int_between(10, 10**6),
        default=300,
        help="held-out segments the measures are taken on (300)",
    )
    grid.add_argument(
        "--window-steps",
        type=int_between(1, 10**9),
        default=None,
        metavar="N",
        help="sessions that follow a learning policy, one per window of N steps of the "
        "pool's run: session k asks about the run's episodes whose last step is within "
        "steps k*N to (k+1)*N - 1, and each budget is scored on the next window's episodes, "
        "with no held-out split (off: every session on the training episodes, scored on "
        "the held-out ones)",
    )
    grid.add_argument(
        "--reward-epochs",
        type=int_between(1, 10_000),
        default=30,
        help="most epochs of reward training per budget (30)",
    )
    grid.add_argument(
        "--workers",
        type=int_between(1, 1024),
        default=os.cpu_count() or 1,
        help="cells at a time, one process and one thread each (the number of cores)",
    )
    grid.add_argument(
        "--out",
        type=Path,
        default=Path("seqrank-out/reward-bench"),
        help="the grid's folder; the same command continues it (seqrank-out/reward-bench)",
    )
