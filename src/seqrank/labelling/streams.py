"""The labelling page's random streams, each named once.

A draw at the page comes from a generator seeded by a seed (a session's, or offline the
run's), the stream's number and the draw's key. The numbers are part of every stored
session: a replay after a kill draws again what the first run drew, so a number never
changes (`tests/labelling/test_streams.py` pins them to the values sessions were stored
with).
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class Stream(IntEnum):
    ROLLOUT = 3  # offline: the episodes' reset seeds and random actions (run seed)
    OFFLINE_SESSION = 4  # offline: a session's pool and its scheme's draws (run seed, session)
    CHAIN = 7  # a team's chain: its scheme's draws (session seed, chain)
    CHAIN_DEFENDER_SIDE = 8  # the side a chain's defender keeps (session seed, chain)
    SECOND_OPINION = 9  # whether an answer is asked of a second person (session seed, index)
    QUESTION_SIDE = 10  # a team's question: the side each segment is shown on (seed, index)
    GOLD = 11  # whether a gold question follows an answer (session seed, index)
    GOLD_ORDER = 12  # the order a member is shown the gold pairs in (0, the member's place)


def stream(seed: int, name: Stream, *keys: int) -> np.random.Generator:
    """The generator of stream `name` for `seed` and the draw's `keys`."""
    return np.random.default_rng([seed, int(name), *keys])


def session_seed(run_seed: int, run: str, session: int) -> int:
    """A session's seed, stored with it: every draw of the session derives from it."""
    words = [run_seed, session, *run.encode()]
    return int(np.random.SeedSequence(words).generate_state(1)[0])


# One person's sessions keep the draws they had before streams were named (no number).
def one_person_draws(seed: int) -> np.random.Generator:
    """A one-person session's scheme draws; the first draw of the same stream, at the
    session's creation, chose the side its defender keeps (`defender_side`)."""
    return np.random.default_rng(seed)


def one_person_side(seed: int, index: int) -> np.random.Generator:
    """A one-person session's question `index`: the side each segment is shown on."""
    return np.random.default_rng([seed, index])
