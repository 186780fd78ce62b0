from __future__ import annotations

import json

import numpy as np

from seqrank.feedback.teachers import ScriptedTeacher, teacher_preset
from seqrank.simulate import run_session, simulate, synthetic_segments


def test_synthetic_segments_shape_and_range():
    rewards = synthetic_segments(100, 50, np.random.default_rng(0))
    assert rewards.shape == (100, 50)
    assert rewards.min() >= 0 and rewards.max() <= 1
    assert rewards.sum(axis=1).std() > 5  # returns are spread out


def test_oracle_sessions_make_no_errors_and_sequential_beats_pairwise():
    rng = np.random.default_rng(0)
    oracle = ScriptedTeacher(teacher_preset("oracle"))
    seq = run_session("sequential", oracle, 40, rng)
    pair = run_session("pairwise", oracle, 40, rng)
    assert seq.asked == pair.asked == 40
    assert seq.inferred_wrong == 0 and seq.asked_wrong == 0
    assert pair.inferred == 0 and seq.inferred > 0


def test_simulation_cells_measure_teacher_noise():
    results = simulate(["root", "sequential"], ["oracle", "mistake", "skip"], 20, 60, seed=3)
    by = {(r.scheme, r.teacher): r for r in results}
    assert len(results) == 6
    assert by[("root", "oracle")].inferred_error_rate == 0
    assert 0.05 < by[("sequential", "mistake")].asked_error_rate < 0.15
    assert by[("root", "mistake")].inferred_error_rate > 0.05
    assert by[("sequential", "skip")].skipped_per_session > 0
    assert (
        by[("root", "oracle")].pairs_per_question
        > by[("sequential", "oracle")].pairs_per_question
        > 1
    )


def test_simulation_is_reproducible_from_its_seed():
    first = simulate(["sequential"], ["noisy"], 10, 20, seed=5)
    again = simulate(["sequential"], ["noisy"], 10, 20, seed=5)
    other = simulate(["sequential"], ["noisy"], 10, 20, seed=6)
    assert first == again and first != other


def _simulate(tmp_path, teachers: str) -> tuple[int, dict]:
    from seqrank.cli import main

    out = tmp_path / "sim"
    args = ["simulate", "--teachers", teachers, "--schemes", "pairwise", "--questions", "20"]
    code = main([*args, "--sessions", "30", "--no-plot", "--out", str(out)])
    payload = json.loads((out / "simulate.json").read_text()) if code == 0 else {}
    return code, payload


def test_simulate_takes_teachers_with_knobs_as_train_and_reward_bench_do(tmp_path):
    """600 answers per teacher: a flip rate of 0.3 reads 0.30 +- 0.02 (one standard error),
    the preset's 0.1 reads 0.10 +- 0.012."""
    code, payload = _simulate(tmp_path, "mistake,eps_mistake=0.3,mistake;gamma=0.9,oracle")
    assert code == 0
    teachers = ["mistake,eps_mistake=0.3", "mistake", "gamma=0.9", "oracle"]
    assert payload["parameters"]["teachers"] == teachers
    rate = {cell["teacher"]: cell["asked_error_rate"] for cell in payload["results"]}
    assert 0.22 < rate["mistake,eps_mistake=0.3"] < 0.38 and 0.05 < rate["mistake"] < 0.15
    assert rate["oracle"] == 0 and rate["gamma=0.9"] > 0  # a myopic teacher errs
    code, payload = _simulate(tmp_path, "oracle,noisy")  # plain lists as before
    assert code == 0 and [c["teacher"] for c in payload["results"]] == ["oracle", "noisy"]


def test_simulate_names_a_bad_teacher_in_one_line_and_writes_nothing(tmp_path, capsys):
    assert _simulate(tmp_path, "oracle;mistake,eps_mistake=2")[0] == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1
    assert "--teachers 'mistake,eps_mistake=2': teacher eps_mistake must be in [0, 1]" in error
    assert _simulate(tmp_path, "human")[0] == 2
    assert "unknown teacher 'human'; accepted: oracle, mistake" in capsys.readouterr().err
    assert not (tmp_path / "sim").exists()


def test_the_terminal_table_keeps_teachers_that_differ_in_a_knob_apart():
    """On a narrow terminal a long teacher name folds onto more lines; it is never cut to
    a prefix that two teachers share ("mistake,e…")."""
    from rich.console import Console

    from seqrank.console_tables import print_simulation

    teachers = ["mistake,eps_mistake=0.2", "mistake,eps_mistake=0.3"]
    results = simulate(["root"], teachers, 10, 2, seed=0)
    console = Console(width=70, record=True)
    print_simulation(console, results)
    shown: list[str] = []
    for line in console.export_text().splitlines():
        cells = line.split("│")
        if len(cells) < 3:
            continue
        if cells[1].strip():  # a row's first line names its scheme
            shown.append("")
        shown[-1] += cells[2].strip()
    assert shown == teachers
