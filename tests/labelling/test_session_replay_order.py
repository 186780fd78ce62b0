"""A page session continued from its database keeps collection order's choice: the stored
pool was stored in the order collected, and the in-order choice reads positions only, so a
new draw that differs from the stored pool (a model's chooser would then fall back to a
uniform draw over the stored pool) does not change which segments come next."""

from __future__ import annotations

import numpy as np

from seqrank.episodes import Segments
from seqrank.feedback.schemes import in_order_choice, uniform_choice
from seqrank.feedback.session import SessionRequest
from seqrank.labelling.db import LabelDB
from seqrank.labelling.session_replay import open_session


def _pool(shift: float) -> Segments:
    features = np.arange(8 * 3 * 2, dtype=np.float32).reshape(8, 3, 2) + shift
    return Segments(features, np.ones((8, 3)), [None] * 8, [None] * 8)


def _request(pool: Segments, chooser) -> SessionRequest:
    in_order = chooser is in_order_choice
    rng = np.random.default_rng(0)
    return SessionRequest("root", 4, 0, pool, chooser, rng, 0.0, in_order=in_order)


def test_a_continued_session_keeps_the_in_order_choice(tmp_path):
    db = LabelDB.in_dir(tmp_path)
    open_session(db, "run", 0, _request(_pool(0.0), in_order_choice))
    again = open_session(db, "run", 0, _request(_pool(100.0), in_order_choice))
    assert again.choices.base is in_order_choice
    assert np.array_equal(again.pool.features, _pool(0.0).features)  # the stored pool
    model_picked = open_session(db, "run", 0, _request(_pool(100.0), max))  # (another chooser)
    assert model_picked.choices.base is uniform_choice
    db.close()
