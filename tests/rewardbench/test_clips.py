"""What the questions cost an annotator (issue 46, item 2): clips watched, counted from what
each session showed, and seconds under the paper's user-study protocol (supplementary
D.7); curves against both."""

from __future__ import annotations

import json

import pytest
from test_reward_bench import SMALL, synthetic_pool

from seqrank.cli import main
from seqrank.feedback.sources import make_source
from seqrank.rewardbench.bench import run_cell
from seqrank.rewardbench.cells import Cell
from seqrank.rewardbench.measures import ANSWER_SECONDS, CLIP_FPS, annotator_seconds
from seqrank.rewardbench.summary import format_table, summarise

CLIP = SMALL.segment_length / 30  # seconds a 20-step clip plays at 30 frames a second


class _Counting:
    """The oracle, counting the distinct segments each session showed."""

    def __init__(self) -> None:
        self.teacher = make_source("oracle")
        self.shown: list[int] = []

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request):
        segments, record = self.teacher.ask_session(request)
        self.shown.append(len({s for a in record.answers for s in (a.first, a.second)}))
        return segments, record


@pytest.mark.parametrize(
    ("scheme", "clips"),
    [
        ("pairwise", [20, 60]),  # two new clips a question
        ("sequential", [11, 33]),  # one new a question, two for a session's first
        ("root", [11, 33]),
    ],
)
def test_clips_are_counted_per_session_as_shown(scheme, clips):
    rows = run_cell(synthetic_pool(), Cell(scheme, "oracle", 2), SMALL)
    assert [r["clips"] for r in rows] == clips
    for row in rows:  # 20-step clips at 30 frames a second, and 3 s a question
        expected = CLIP * row["clips"] + 3.0 * row["questions"]
        assert row["annotator_seconds"] == pytest.approx(expected)


def test_ranked_clips_are_the_segments_its_sessions_showed():
    """A ranked question may compare a new segment with several kept ones: fewer new clips
    than questions, counted from the sessions' own answers."""
    source = _Counting()
    rows = run_cell(synthetic_pool(), Cell("ranked", "oracle", 1), SMALL, source)
    assert [r["clips"] for r in rows] == [source.shown[0], sum(source.shown)]
    assert rows[-1]["clips"] < rows[-1]["questions"] + 3  # 3 sessions: at most 33


def test_the_protocol_is_the_papers_and_the_labelling_pages():
    from seqrank.labelling.app import ServerOptions

    page = ServerOptions()
    assert (CLIP_FPS, ANSWER_SECONDS) == (page.fps, page.countdown_s) == (30, 3.0)
    # a 50-step pairwise question: two clips of 5/3 s, then 3 s to answer
    assert annotator_seconds(2, 1, 50) == pytest.approx(2 * 50 / 30 + 3)
    assert annotator_seconds(11, 10, 50) == pytest.approx(11 * 50 / 30 + 30)


def _rows():
    rows = []
    for seed in range(2):
        for scheme, per_question in (("pairwise", 2), ("sequential", 1)):
            for questions in (10, 20):
                clips = per_question * questions + (scheme == "sequential")
                rows.append(
                    {
                        "task": "t", "teacher": "oracle", "scheme": scheme, "seed": seed,
                        "questions": questions, "pairs": questions, "accuracy": 0.7 + seed / 10,
                        "spearman": 0.5, "inferred_wrong": None, "clips": clips,
                        "annotator_seconds": annotator_seconds(clips, questions, 50),
                    }
                )  # fmt: skip
    return rows


def test_the_summary_carries_clips_and_seconds_and_curves_use_them(tmp_path, capsys):
    summary = summarise(_rows())
    pairwise = next(e for e in summary if e["scheme"] == "pairwise" and e["questions"] == 20)
    assert pairwise["clips"] == 40 and pairwise["annotator_seconds"] == pytest.approx(
        40 * 50 / 30 + 60
    )
    table = format_table(summary)
    assert "| clips | annotator minutes |" in table.splitlines()[0]
    assert f"| 40 | {(40 * 50 / 30 + 60) / 60:.1f} |" in table
    folder = tmp_path / "grid"
    folder.mkdir()
    (folder / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in _rows()))
    assert main(["reward-bench", "report", str(folder)]) == 0
    for name in ("curves_t.png", "curves_t_clips.png", "curves_t_seconds.png"):
        assert (folder / name).read_bytes()[:4] == b"\x89PNG"
    # rows written before clips were counted: no such curves, '-' in the table
    old = [{k: v for k, v in r.items() if k not in ("clips", "annotator_seconds")} for r in _rows()]
    (folder / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in old))
    for name in ("curves_t_clips.png", "curves_t_seconds.png"):
        (folder / name).unlink()
    assert main(["reward-bench", "report", str(folder)]) == 0
    assert not (folder / "curves_t_clips.png").exists()
    printed = capsys.readouterr().out.splitlines()
    assert any(line.endswith("| 40 | 2.1 |") for line in printed)  # the first report
    assert any(line.endswith("| - | - | - | - |") for line in printed)  # the second
