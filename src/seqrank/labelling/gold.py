"""Gold pairs at a team's page (issue 49): pairs whose order the operator knows, shown now
and then to each member among their own questions, unannounced.

A gold file is a label file (`seqrank.feedback.label_file`) of the same task and segment
length, for instance one the operator answered with `seqrank label offline`; its strict
answers ("first" or "second") are the gold pairs. Its segments must keep their physics
states: the page renders their clips as it renders any other.

After each answer of a chain, with probability `GOLD_SHARE`, its author is given the next
gold pair they have not been shown (in an order of their own). The gold segments and
questions are stored under the run `GOLD_RUN`, never in a session: they ask nothing of the
budget, train nothing and are not exported as labels; their answers are reliability
evidence beside the gold answer (`seqrank.feedback.peer_reliability.GOLD`), which counts
against whoever contradicts it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from seqrank.envs import same_task
from seqrank.episodes import Segments
from seqrank.feedback.label_file import LabelFile, read_label_file
from seqrank.labelling.crowd_keys import GOLD_RUN
from seqrank.labelling.db import LabelDB

GOLD_SHARE = 0.1  # a gold question after about one answer in ten, for each member
GOLD_META = "gold_pairs"  # the stored pairs, as segment ids and the known order
GOLD_SOURCE = "gold_source"  # the file they were read from


@dataclass(frozen=True)
class GoldPairs:
    """Gold pairs read from `source`: `pairs` are (row, row, first preferred) of `segments`."""

    source: str  # the file, as an absolute path (a refusal names it from anywhere)
    segments: Segments
    pairs: tuple[tuple[int, int, bool], ...]


def read_gold(path: Path, task: str, segment_length: int) -> GoldPairs:
    """The gold pairs of the label file `path` for `task`; ValueError naming the file and
    what is wrong (no file, another task or segment length, no strict answer, a pair
    answered both ways, a segment without the physics states its clip needs)."""
    where = f"gold file {path}"
    if not Path(path).is_file():
        raise ValueError(f"{where} does not exist")
    labels = read_label_file(path)
    header = labels.header
    if not same_task(str(header.get("task")), task):
        raise ValueError(f"{where} is of task {header.get('task')!r}; this run's is {task!r}")
    known = _known_orders(labels, where)
    names = list(dict.fromkeys(name for pair in known for name in pair))
    lengths = sorted({len(labels.segments[name]["features"]) for name in names})
    if lengths != [segment_length]:
        steps = " and ".join(map(str, lengths))
        raise ValueError(
            f"{where} holds segments of {steps} steps; this run asks about {segment_length}: "
            "its gold questions would stand out"
        )
    bare = [name for name in names if labels.segments[name].get("states") is None]
    if bare:
        raise ValueError(
            f"{where}: segment {bare[0]!r} keeps no physics states, so its clip cannot be "
            "shown; use a file whose segments keep their states (the labelling page's, "
            "on a task with MuJoCo state)"
        )
    row = {name: k for k, name in enumerate(names)}
    pairs = tuple((row[a], row[b], first) for (a, b), first in known.items())
    return GoldPairs(str(Path(path).resolve()), labels.session_segments(names), pairs)


def _known_orders(labels: LabelFile, where: str) -> dict[tuple[str, str], bool]:
    """Each strictly answered pair and whether its first segment is preferred."""
    known: dict[tuple[str, str], bool] = {}
    for answer in labels.answers:
        if answer["answer"] not in ("first", "second"):
            continue
        first_better = answer["answer"] == "first"
        pair, order = (answer["first"], answer["second"]), first_better
        if pair[0] > pair[1]:
            pair, order = (pair[1], pair[0]), not first_better
        if known.setdefault(pair, order) != order:
            raise ValueError(
                f"{where}: the pair {pair[0]} / {pair[1]} is answered both ways; "
                "a gold pair has one known order"
            )
    if not known:
        raise ValueError(f"{where} holds no 'first' or 'second' answer to use as a gold pair")
    return known


def store_gold(db: LabelDB, gold: GoldPairs) -> tuple[tuple[int, int, bool], ...]:
    """Keep the gold segments and pairs in the database (the same again on a restart);
    returns the pairs as segment ids. ValueError, with nothing stored, when the database
    holds other gold."""
    check_gold(db, gold)
    if db.get_meta(GOLD_META) is None:
        db.store_segments(GOLD_RUN, 0, gold.segments)
    pairs = _pair_ids(db, gold)
    db.set_meta(GOLD_META, json.dumps([list(pair) for pair in pairs]))
    if db.get_meta(GOLD_SOURCE) is None:
        db.set_meta(GOLD_SOURCE, gold.source)
    return pairs


def check_gold(db: LabelDB, gold: GoldPairs) -> None:
    """ValueError when the database holds gold pairs other than `gold` (read only: a
    command checks this before it starts anything)."""
    stored = db.get_meta(GOLD_META)
    if stored is None:
        return
    same = np.array_equal(db.pool(GOLD_RUN, 0).features, gold.segments.features)
    if not same or stored != json.dumps([list(pair) for pair in _pair_ids(db, gold)]):
        raise ValueError(
            f"this labelling directory was started with the gold pairs of "
            f"{db.get_meta(GOLD_SOURCE)}, not {gold.source}'s: give that file again (or leave "
            "--gold out: the directory keeps its gold), or label in another directory"
        )


def _pair_ids(db: LabelDB, gold: GoldPairs) -> tuple[tuple[int, int, bool], ...]:
    """`gold`'s pairs as the ids its segments are stored under."""
    ids = db.segment_ids(GOLD_RUN, 0)
    return tuple((ids[a], ids[b], first) for a, b, first in gold.pairs)


def stored_gold(db: LabelDB) -> tuple[tuple[int, int, bool], ...]:
    """The gold pairs a directory was started with (none: empty): a rerun without
    `--gold` keeps asking them."""
    stored = db.get_meta(GOLD_META)
    return () if stored is None else tuple((a, b, bool(f)) for a, b, f in json.loads(stored))
