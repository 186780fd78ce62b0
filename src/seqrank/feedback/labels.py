"""Every labelled pair of a run, with the segments it refers to, as training tensors."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from seqrank.episodes import Segments
from seqrank.feedback.checking import contradicts_itself
from seqrank.feedback.closure import Augmentation
from seqrank.feedback.schemes import SessionRecord
from seqrank.types import Answer


class LabelStore:
    def __init__(self) -> None:
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
        for pair in augmentation.pairs:
            self.first.append(offset[pair.first])
            self.second.append(offset[pair.second])
            self.labels.append(pair.label)
            self.inferred.append(pair.inferred)
            self.session.append(session)
        if record is None:
            return
        for asked in record.answers:
            question = asked.question
            first, second = offset[question.first], offset[question.second]
            row = (session, record.scheme, first, second, asked.answer.value)
            self.asked.append((*row, question.first_is_defender))

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
        first, second = np.asarray(self.first[rows]), np.asarray(self.second[rows])
        used, inverse = np.unique(np.concatenate([first, second]), return_inverse=True)
        segments = torch.as_tensor(np.stack([self.segments[i] for i in used]), device=device)
        first_t = torch.as_tensor(inverse[: len(first)], dtype=torch.long, device=device)
        second_t = torch.as_tensor(inverse[len(first) :], dtype=torch.long, device=device)
        labels = torch.as_tensor(self.labels[rows], dtype=torch.float32, device=device)
        return segments, first_t, second_t, labels

    def state_dict(self) -> dict[str, Any]:
        return dict(vars(self))

    def load_state_dict(self, state: dict[str, Any]) -> None:
        for name, value in state.items():
            setattr(self, name, value)
