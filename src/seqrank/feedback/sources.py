"""Who answers a run's questions, from its `--teacher` value: a scripted preset, labels
recorded earlier (`replay:FILE`), a simulated crowd (`crowd:oracle+noisy`), or a person
(`human`, served by `seqrank label online`)."""

from __future__ import annotations

from seqrank.errors import SettingError, setting
from seqrank.feedback.overlap import EVIDENCE_UNTIL, OVERLAP
from seqrank.feedback.session import FeedbackSource, ScriptedSource
from seqrank.feedback.teachers import ScriptedTeacher, parse_teacher


def make_source(
    teacher: str,
    overlap: float = OVERLAP,
    overlap_until: int = EVIDENCE_UNTIL,
    closure_checks: bool = False,
) -> FeedbackSource:
    """The feedback source a `--teacher` value stands for; ValueError for `human` (it
    needs the labelling page) and for values `parse_teacher` refuses. `overlap`: the
    share of a crowd's answers also asked of a second member; `overlap_until`: every
    answer of a member with fewer shared answers than this (`seqrank.feedback.overlap`);
    `closure_checks`: second opinions on inferred pairs (`seqrank.feedback.closure_checks`)."""
    spec = parse_teacher(teacher)
    if spec.kind == "crowd":
        from seqrank.feedback.crowd import CrowdSource

        return CrowdSource(spec.members, overlap, overlap_until, closure_checks)
    if spec.kind == "replay":
        from seqrank.feedback.replay import ReplaySource

        assert spec.replay_file is not None
        return ReplaySource.from_file(spec.replay_file)
    if spec.kind == "human":
        raise SettingError(
            f"{setting('teacher')} 'human' answers on the labelling page: start the run with "
            "`seqrank label online ...` instead of `seqrank train`"
        )
    assert spec.scripted is not None
    return ScriptedSource(ScriptedTeacher(spec.scripted))
