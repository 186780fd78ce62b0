"""Every labelled pair of a run, with the segments it refers to, as training tensors."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from seqrank.episodes import Segments
from seqrank.feedback.checking import contradicts_itself
from seqrank.feedback.closure import Augmentation
from seqrank.feedback.crowd_record import CrowdRecord, EvidenceRow, session_evidence
from seqrank.feedback.peer_reliability import estimate_from_peers
from seqrank.feedback.reliability import (
    MODEL,
    Reliability,
    estimate_reliability,
    evidence_rows,
    soft_label,
)
from seqrank.feedback.schemes import SessionRecord
from seqrank.types import Answer, LabelledPair

# a crowd's answer as stored: (first, second) as store ids, answer, annotator, the model's
# P(first) before the session (None before its first fit)
CrowdAnswer = EvidenceRow


class LabelStore:
    """`weighting` "reliability": a crowd's labels train as the probability that their
    annotator is right; "drop": the labels of a flagged annotator (their answers and what
    the closure infers from them) are left out of reward training; "reask": as drop, and
    the crowd asks a member flagged before a session's questions again of someone else
    (`distrusted`), whose answers train; "soften": a flagged annotator's labels train as
    the probability that they are right (left out at an estimate of 1/2 or less), the
    others' as answered; "none": as answered. Reliability is estimated from the other
    people's answers (`seqrank.feedback.peer_reliability`)."""

    def __init__(self, weighting: str = "none") -> None:
        self.segments: list[np.ndarray] = []  # (H, obs+act) each
        self.segment_returns: list[float] = []
        self.segment_rewards: list[np.ndarray] = []  # true per-step rewards, for the export
        self.first: list[int] = []
        self.second: list[int] = []
        self.labels: list[float] = []
        self.inferred: list[bool] = []
        self.session: list[int] = []
        # provenance, to re-render a segment: physics states (when recorded) and task index
        self.segment_states: list[np.ndarray | None] = []
        self.segment_contexts: list[int | None] = []
        # every asked question in order, skips included, for the label export:
        # (session, scheme, first, second, answer, first is the defender); ids index segments
        self.asked: list[tuple[int, str, int, int, str, bool]] = []
        # a crowd's: each pair's annotator ("" for one teacher), every answer (second
        # opinions too) as reliability evidence
        self.weighting = weighting
        self.annotator: list[str] = []
        self.crowd_answers: list[CrowdAnswer] = []

    def __len__(self) -> int:
        return len(self.labels)

    def add_session(
        self,
        segments: Segments,
        true_returns: np.ndarray,
        used: tuple[int, ...],
        augmentation: Augmentation,
        session: int,
        record: SessionRecord | None = None,
    ) -> None:
        """Store the session's segments (pool ids `used`), its labelled pairs and (given
        the session's record) its questions and answers."""
        offset = {pool_id: len(self.segments) + k for k, pool_id in enumerate(used)}
        for pool_id in used:
            self.segments.append(segments.features[pool_id])
            self.segment_returns.append(float(true_returns[pool_id]))
            self.segment_rewards.append(np.asarray(segments.rewards[pool_id], np.float32))
            self.segment_states.append(segments.states[pool_id])
            self.segment_contexts.append(segments.contexts[pool_id])
        crowd = None if record is None else record.crowd
        owner = _segment_owners(record) if record is not None and crowd is not None else {}
        for pair in augmentation.pairs:
            self._add_pair(pair, offset, session, owner.get(pair.first, ""))
        if crowd is not None:
            self._add_crowd(crowd, record.answers if record else (), offset, session)
        if record is None:
            return
        for asked in record.answers:
            question = asked.question
            first, second = offset[question.first], offset[question.second]
            row = (session, record.scheme, first, second, asked.answer.value)
            self.asked.append((*row, question.first_is_defender))

    def _add_pair(
        self, pair: LabelledPair, offset: dict[int, int], session: int, annotator: str
    ) -> None:
        self.first.append(offset[pair.first])
        self.second.append(offset[pair.second])
        self.labels.append(pair.label)
        self.inferred.append(pair.inferred)
        self.session.append(session)
        self.annotator.append(annotator)

    def _add_crowd(
        self, crowd: CrowdRecord, answers: Any, offset: dict[int, int], session: int
    ) -> None:
        """The second opinions as asked pairs of their own (never chained), and every
        answer as reliability evidence."""
        for opinion in crowd.second_opinions:
            asked = opinion.answered
            if asked.answer.label is not None:
                pair = LabelledPair(asked.first, asked.second, asked.answer.label, False)
                self._add_pair(pair, offset, session, opinion.annotator)
        evidence = session_evidence(crowd, answers, offset.__getitem__)
        self.crowd_answers += evidence.rows()

    def reliability(self) -> dict[str, Reliability]:
        """A crowd's annotators' reliability from every answer so far (empty for one
        teacher); the reward model's own, as a voter, is left out."""
        return estimate_from_peers(evidence_rows(self.crowd_answers))

    def reliability_with_model(self) -> dict[str, Reliability]:
        """The same from `seqrank.feedback.reliability`'s estimator, the reward model a
        voter (the estimator before issue 49; kept for the benchmark's comparison)."""
        estimates = estimate_reliability(evidence_rows(self.crowd_answers))
        return {name: r for name, r in estimates.items() if name != MODEL}

    def distrusted(self) -> frozenset[str]:
        """Under `reask`, the annotators flagged so far, whose questions the next session
        asks again of someone else (`SessionRequest.distrusted`); nobody under another
        weighting, or when everybody is flagged (nobody is trusted more)."""
        if self.weighting != "reask" or not self.crowd_answers:
            return frozenset()
        trust = self.reliability()
        flagged = frozenset(name for name, r in trust.items() if r.flagged)
        return frozenset() if flagged == set(trust) else flagged

    def kept(self) -> list[bool]:
        """Which pairs reward training fits: all, or (`drop`, `reask`) all but a flagged
        annotator's, or (`soften`) all but those of a flagged annotator estimated right
        half the time or less."""
        if self.weighting not in ("drop", "reask", "soften") or not any(self.annotator):
            return [True] * len(self.labels)
        found = self.reliability()
        flagged = {name for name, r in found.items() if r.flagged}
        if self.weighting == "soften":
            flagged = {name for name in flagged if found[name].estimate <= 0.5}
        kept = [name not in flagged for name in self.annotator]
        return kept if any(kept) else [True] * len(kept)  # (all flagged: none trusted more)

    def asked_mask(self) -> torch.Tensor:
        """Of the pairs `tensors` gives, which were asked (not inferred)."""
        kept = self.kept()
        return torch.tensor([not i for i, k in zip(self.inferred, kept, strict=True) if k])

    def training_labels(self) -> list[float]:
        """The labels reward training fits: as answered, or (a crowd, weighted by
        reliability) each the probability that it is right: everybody's (`reliability`),
        or a flagged annotator's only (`soften`)."""
        if self.weighting not in ("reliability", "soften") or not any(self.annotator):
            return list(self.labels)
        trust = self.reliability()
        if self.weighting == "soften":
            trust = {name: r for name, r in trust.items() if r.flagged}
        return [
            soft_label(label, trust[name]) if name in trust else label
            for label, name in zip(self.labels, self.annotator, strict=True)
        ]

    def teacher_contradicted(self) -> bool:
        """Whether two stored answers to the same pair disagree (a re-check that did not
        confirm): `augment checked` then asks big answers twice more."""
        return contradicts_itself((f, s, Answer(a)) for _, _, f, s, a, _ in self.asked)

    def tensors(
        self, device: torch.device, last: int | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """(segments (S, H, D), first (P,), second (P,), labels (P,)).

        With `last`, only the most recent `last` pairs and just the segments they use.
        """
        rows = slice(-last, None) if last else slice(None)
        kept = np.asarray(self.kept()[rows], dtype=bool)
        first, second = np.asarray(self.first[rows])[kept], np.asarray(self.second[rows])[kept]
        used, inverse = np.unique(np.concatenate([first, second]), return_inverse=True)
        segments = torch.as_tensor(np.stack([self.segments[i] for i in used]), device=device)
        first_t = torch.as_tensor(inverse[: len(first)], dtype=torch.long, device=device)
        second_t = torch.as_tensor(inverse[len(first) :], dtype=torch.long, device=device)
        trained = np.asarray(self.training_labels()[rows], dtype=np.float32)[kept]
        labels = torch.as_tensor(trained, device=device)
        return segments, first_t, second_t, labels

    def state_dict(self) -> dict[str, Any]:
        return dict(vars(self))

    def load_state_dict(self, state: dict[str, Any]) -> None:
        for name, value in state.items():
            setattr(self, name, value)
        if len(self.annotator) < len(self.labels):  # saved before crowds had annotators
            self.annotator = [""] * len(self.labels)


def _segment_owners(record: SessionRecord) -> dict[int, str]:
    """Pool id -> the annotator whose chain drew the segment."""
    assert record.crowd is not None
    owners: dict[int, str] = {}
    for asked, name in zip(record.answers, record.crowd.answered_by, strict=True):
        owners.setdefault(asked.first, name)
        owners.setdefault(asked.second, name)
    return owners
