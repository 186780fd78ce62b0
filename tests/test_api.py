"""The Python API (`import seqrank`) and the examples that use it, run as a user would."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import seqrank

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def test_public_names_are_exported_with_docstrings_and_load_lazily():
    for name in seqrank.__all__:
        value = getattr(seqrank, name)
        if callable(value):
            assert value.__doc__, name
    assert seqrank.SCHEMES == ("pairwise", "sequential", "root", "ranked")
    with pytest.raises(AttributeError, match="no attribute 'Trainer'"):
        _ = seqrank.Trainer
    check = "import sys, seqrank; print('torch' in sys.modules)"
    light = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True)
    assert light.stdout.strip() == "False"  # importing the package loads no torch


def test_a_scheme_runs_over_a_plain_function_and_its_answers_close():
    values = [5.0, 1.0, 4.0, 2.0, 3.0]

    def ask(first: int, second: int) -> seqrank.Answer:
        return seqrank.Answer.FIRST if values[first] > values[second] else seqrank.Answer.SECOND

    record = seqrank.run_scheme("root", len(values), 4, ask, seed=2)
    assert record.asked == 4 and record.scheme == "root"
    closed = seqrank.close_preferences(record.answers, true_returns=values)
    assert closed.stats.asked_wrong == 0 and closed.stats.inferred_wrong == 0
    with pytest.raises(ValueError, match="unknown scheme 'best'"):
        seqrank.run_scheme("best", 5, 2, ask)


def test_make_config_checks_like_the_command_line():
    config = seqrank.make_config("walker_walk", steps=70_000)
    assert config.steps == 70_000 and config.hidden == 256  # the small preset
    with pytest.raises(ValueError, match="unknown scheme 'best'"):
        seqrank.make_config(scheme="best")
    with pytest.raises(ValueError, match="unknown setting 'bogus'; settings are TrainConfig"):
        seqrank.make_config(bogus=1)


def _example(*args: str, cwd: Path, stdin: str | None = None) -> str:
    done = subprocess.run(
        [sys.executable, *args], cwd=cwd, input=stdin, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_the_examples_run(tmp_path):
    asked = _example(str(EXAMPLES / "ask_in_terminal.py"), cwd=tmp_path, stdin="1\n2\n=\n")
    assert "asked 3" in asked
    closed = _example(str(EXAMPLES / "close_a_graph.py"), cwd=tmp_path)
    assert "6 answered, 1 inferred: [(3, 5)]" in closed and "1 cycle(s) over 3" in closed
    judge = str(EXAMPLES / "train_with_a_judge.py")
    trained = _example(judge, "--out", "judge", "--steps", "2100", cwd=tmp_path)
    assert "asked 30" in trained
    run = seqrank.load_run(tmp_path / "judge")
    assert run.summary is not None and [s for s, _ in run.evaluations()][-1] == 2_100
    looked = _example(str(EXAMPLES / "load_a_run.py"), "judge", cwd=tmp_path)
    assert "one more episode with the saved policy: return" in looked


def test_make_config_takes_the_scale_auto_that_the_cli_defaults_to():
    """auto is paper on CUDA and small elsewhere, as `seqrank train --scale auto`."""
    import seqrank

    assert seqrank.make_config("walker_walk", "auto", device="cpu").scale == "small"
    assert seqrank.make_config("walker_walk", "auto", device="cpu").hidden == 256
    with pytest.raises(ValueError, match="unknown scale 'huge'; accepted: auto, paper, small"):
        seqrank.make_config("walker_walk", "huge")
