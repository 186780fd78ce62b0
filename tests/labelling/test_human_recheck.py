"""The labelling page keeps a session's re-check opinions with the session."""

from __future__ import annotations

import numpy as np

from seqrank.episodes import Segments
from seqrank.feedback.checking import Recheck
from seqrank.feedback.schemes import in_order_choice
from seqrank.feedback.session import SessionRequest
from seqrank.labelling.db import LabelDB
from seqrank.labelling.human import Hub, HumanSource, _PageSession
from seqrank.types import Answer


def pool(values: list[float], shift: float) -> Segments:
    n = len(values)
    features = np.arange(n * 2, dtype=np.float64).reshape(n, 2, 1) + shift
    rewards = np.array([[v / 2, v / 2] for v in values])
    return Segments(features, rewards, [None] * n, [None] * n)


def test_a_resumed_session_asks_with_the_opinions_it_was_first_asked_with(tmp_path, monkeypatch):
    values = [float(v) for v in range(10)]  # in order every challenger wins

    def answer_truly(self: _PageSession, first: int, second: int) -> Answer:
        self.questions_asked += 1
        return Answer.FIRST if values[first] > values[second] else Answer.SECOND

    monkeypatch.setattr(_PageSession, "ask", answer_truly)
    hub = Hub(LabelDB(tmp_path / "labels.sqlite"), None)  # type: ignore[arg-type]
    source = HumanSource(hub, "online", seed=0)

    def request(segments: Segments, recheck: Recheck) -> SessionRequest:
        rng = np.random.default_rng(0)
        return SessionRequest("root", 7, 0, segments, in_order_choice, rng, 0.0, recheck=recheck)

    agrees = Recheck(model_returns=tuple(values))
    stored, first = source.ask_session(request(pool(values, 0.0), agrees))
    assert len(set((a.first, a.second) for a in first.answers)) == 7  # the model spared repeats
    # the run is resumed and samples another pool, with no opinions yet: the session is the
    # stored one, asked with the stored opinions
    again_pool, again = source.ask_session(request(pool(values, 100.0), Recheck()))
    assert np.array_equal(again_pool.features, stored.features)
    assert again.answers == first.answers and again.vouched == first.vouched
    hub.db.close()
