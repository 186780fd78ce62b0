"""`--teacher replay:FILE`: train from labels recorded earlier instead of asking anyone.

Feedback session k of the run uses the k-th recorded session of the file (in the order the
file lists them), with its own segments and answers; transitive labels are inferred again
from the recorded scheme. When the file runs out, the run asks for no more feedback; when
the run's budget ends within a session, that session's first answers are replayed.

The file fixes some of the run's settings (`Recorded`: task, scheme, segment length,
questions per session, answers in all); `config.resolve_config` makes a replaying
run take them and refuses settings given otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from seqrank.episodes import Segments
from seqrank.feedback.label_file import LabelFile, read_label_file
from seqrank.feedback.schemes import SessionRecord
from seqrank.feedback.session import SessionRequest
from seqrank.types import Answer, AnsweredQuestion, Question


@dataclass(frozen=True)
class Recorded:
    """What a label file fixes of a run that replays it."""

    file: str
    task: str | None  # None: a file written before headers named the task
    scheme: str
    segment_length: int
    session_questions: int  # the most answers a recorded session holds
    answers: int


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
        """The file's segments fit the task's features. Whether it was recorded on this
        task is for the layers that know the tasks' names (`config.rules.check_recorded`,
        `check_recorded_task`): feedback stays below the environments."""
        width = len(next(iter(self.labels.segments.values()))["features"][0])
        if width != obs_dim + act_dim:
            raise ValueError(
                f"label file {self.source} has {width} features per step; task {task} "
                f"needs {obs_dim + act_dim} (observation + action)"
            )

    def recorded(self) -> Recorded:
        """The settings these labels were recorded with; ValueError for a file that mixes
        schemes or segment lengths (no one run's settings describe it)."""
        schemes = {a["scheme"] for a in self.labels.answers}
        lengths = {len(s["features"]) for s in self.labels.segments.values()}
        self._refuse_mixed("schemes", schemes)
        self._refuse_mixed("segment lengths", lengths)
        sizes = [len(self._answers(session)) for session in range(len(self.sessions))]
        task = self.labels.header.get("task")
        answers = len(self.labels.answers)
        return Recorded(self.source, task, schemes.pop(), lengths.pop(), max(sizes), answers)

    def _refuse_mixed(self, what: str, values: set[str] | set[int]) -> None:
        if len(values) > 1:
            shown = ", ".join(str(v) for v in sorted(values))
            raise ValueError(
                f"label file {self.source} holds several {what} ({shown}); a run replays "
                "labels of one: export those of one run"
            )

    def _answers(self, session: int) -> list[dict[str, Any]]:
        key = self.sessions[session]
        return [a for a in self.labels.answers if (a["run"], a["session"]) == key]

    def ask_session(self, request: SessionRequest) -> tuple[Segments, SessionRecord]:
        answers = self._answers(request.session)[: request.questions]
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
