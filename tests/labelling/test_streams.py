"""The page's random streams and keys keep the numbers stored sessions were made with
(issue 48, item 3): a replay after the move draws what the first run drew."""

from __future__ import annotations

import numpy as np
import pytest

from seqrank.labelling.crowd_keys import ChainStep, SecondOpinionOf, key_of
from seqrank.labelling.streams import (
    Stream,
    one_person_draws,
    one_person_side,
    session_seed,
    stream,
)

# the numbers each stream was drawn with before it was named
BEFORE = {
    Stream.ROLLOUT: 3,
    Stream.OFFLINE_SESSION: 4,
    Stream.CHAIN: 7,
    Stream.CHAIN_DEFENDER_SIDE: 8,
    Stream.SECOND_OPINION: 9,
    Stream.QUESTION_SIDE: 10,
}


@pytest.mark.parametrize(("name", "number"), BEFORE.items())
def test_a_named_stream_draws_what_its_number_drew(name, number):
    for seed, keys in [(0, ()), (12345, (2,)), (2**40 + 7, (100_003,))]:
        old = np.random.default_rng([seed, number, *keys]).random(4)
        assert np.array_equal(stream(seed, name, *keys).random(4), old)


def test_the_streams_are_distinct_and_every_one_is_pinned():
    assert set(BEFORE) == set(Stream)
    assert len({int(s) for s in Stream}) == len(Stream)


def test_a_session_seed_and_one_persons_draws_are_as_stored():
    seed = session_seed(3, "online", 2)
    assert seed == int(np.random.SeedSequence([3, 2, *b"online"]).generate_state(1)[0])
    assert seed == 2847668404  # a stored session's seed, worked out once
    assert one_person_draws(seed).random() == np.random.default_rng(seed).random()
    assert one_person_side(seed, 5).random() == np.random.default_rng([seed, 5]).random()


def test_keys_encode_as_stored_sessions_hold_them():
    assert ChainStep(0, 0).index == 0
    assert ChainStep(2, 7).index == 200_007
    assert SecondOpinionOf(ChainStep(2, 7)).index == -200_008
    assert SecondOpinionOf(ChainStep(0, 0)).index == -1
    for index in (0, 5, 100_000, 300_042, -1, -6, -100_001, -300_043):
        assert key_of(index).index == index
    with pytest.raises(ValueError):
        ChainStep(0, 100_000)
