"""A team's labelling page: its annotators with their tokens, and how work is shared out
(`seqrank.labelling.crowd_team`, `seqrank.labelling.crowd_source`)."""

from __future__ import annotations

from dataclasses import dataclass

from seqrank.feedback.overlap import OVERLAP
from seqrank.labelling.crowd_db import CrowdTables


@dataclass
class CrowdSettings:
    tokens: dict[str, str]  # annotator -> their token, in the order given
    operator_token: str  # the operator page's (`/operator`); annotators' tokens cannot open it
    tables: CrowdTables
    overlap: float = OVERLAP  # share of answers also asked of a second annotator
    reassign_after: float = 60.0  # seconds a question waits before it is handed over
    # every answer of an annotator with fewer answers shared with somebody else is asked
    # again of two others (`seqrank.feedback.overlap`); 0: the share `overlap` only
    overlap_until: int = 0
    # gold pairs (`seqrank.labelling.gold`): stored segment ids and whether the first is
    # preferred; empty: none
    gold: tuple[tuple[int, int, bool], ...] = ()

    @property
    def annotators(self) -> list[str]:
        return list(self.tokens)
