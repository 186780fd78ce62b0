"""`--teacher replay:FILE`: train from labels recorded earlier instead of asking anyone.

Feedback session k of the run uses the k-th recorded session of the file (in the order the
file lists them), with its own segments and answers; transitive labels are inferred again
from the recorded scheme. When the file runs out, the run asks for no more feedback.
"""

from __future__ import annotations

from pathlib import Path

from seqrank.envs import canonical_task
from seqrank.episodes import Segments
from seqrank.feedback.label_file import LabelFile, read_label_file
from seqrank.feedback.schemes import SessionRecord
from seqrank.feedback.session import SessionRequest
from seqrank.types import Answer, AnsweredQuestion, Question


class ReplaySource:
    def __init__(self, labels: LabelFile, source: str):
        self.labels, self.source = labels, source
        self.sessions = labels.sessions()
        if not self.sessions:
            raise ValueError(f"label file {source} holds no answers to replay")

    @classmethod
    def from_file(cls, path: Path | str) -> ReplaySource:
        return cls(read_label_file(path), str(path))

    def has_session(self, session: int) -> bool:
        return session < len(self.sessions)

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        recorded = self.labels.header.get("task")
        if recorded is not None and canonical_task(recorded) != canonical_task(task):
            raise ValueError(f"label file {self.source} was recorded on {recorded}, not {task}")
        width = len(next(iter(self.labels.segments.values()))["features"][0])
        if width != obs_dim + act_dim:
            raise ValueError(
                f"label file {self.source} has {width} features per step; task {task} "
                f"needs {obs_dim + act_dim} (observation + action)"
            )

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        run, session = self.sessions[request.session]
        answers = [a for a in self.labels.answers if (a["run"], a["session"]) == (run, session)]
        names = list(dict.fromkeys(n for a in answers for n in (a["first"], a["second"])))
        local = {name: k for k, name in enumerate(names)}
        record = SessionRecord(
            answers[0]["scheme"],
            tuple(
                AnsweredQuestion(
                    Question(
                        k, local[a["first"]], local[a["second"]], a.get("defender") is not None
                    ),
                    Answer(a["answer"]),
                )
                for k, a in enumerate(answers)
            ),
            tuple(range(len(names))),
        )
        return self.labels.session_segments(names), record
