"""`LabelStore.asked_mask`: which of the pairs reward training fits were asked, the mask
the early stop counts under `--reward-stop-on asked` (a dropped annotator's pairs are
not among them)."""

from __future__ import annotations

import pytest

from seqrank.feedback.labels import LabelStore
from seqrank.feedback.reliability import Reliability


def test_the_mask_marks_the_asked_pairs_and_not_the_inferred():
    labels = LabelStore()
    labels.labels, labels.annotator = [1.0, 0.0, 1.0, 1.0], ["", "", "", ""]
    labels.inferred = [False, True, False, True]
    assert labels.asked_mask().tolist() == [True, False, True, False]


def test_the_mask_follows_the_pairs_a_dropped_annotator_leaves(monkeypatch: pytest.MonkeyPatch):
    labels = LabelStore("drop")
    labels.labels, labels.annotator = [1.0, 0.0, 1.0, 0.0], ["a", "b", "a", "b"]
    labels.inferred = [False, False, True, True]

    def b_flagged(_self: LabelStore) -> dict[str, Reliability]:
        return {
            "a": Reliability("a", 0.95, 0.9, 1.0, 50, 0, None),
            "b": Reliability("b", 0.3, 0.2, 0.4, 50, 0, None),
        }

    monkeypatch.setattr(LabelStore, "reliability", b_flagged)
    assert labels.kept() == [True, False, True, False]
    assert labels.asked_mask().tolist() == [True, False]  # a's asked pair, a's inferred one
