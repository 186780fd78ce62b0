from __future__ import annotations

import json

import numpy as np
import pytest

from seqrank.episodes import Segments
from seqrank.feedback.closure import augment
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.peer_reliability import FLAG_AFTER, FLAG_BELOW
from seqrank.feedback.schemes import SessionRecord
from seqrank.feedback.session import SessionRequest
from seqrank.feedback.teachers import ScriptedTeacher, teacher_preset
from seqrank.simulate import (
    CrowdSettings,
    run_crowd_sessions,
    run_session,
    simulate,
    synthetic_segments,
)


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


def _simulate(tmp_path, teachers: str, *extra: str) -> tuple[int, dict]:
    """`seqrank simulate` of `teachers`, 30 pairwise sessions of 20 questions unless
    `extra` options say otherwise; (exit code, simulate.json)."""
    from seqrank.cli import main

    out = tmp_path / "sim"
    args = ["simulate", "--teachers", teachers, "--schemes", "pairwise", "--questions", "20"]
    code = main([*args, "--sessions", "30", "--no-plot", "--out", str(out), *extra])
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


# --- a crowd: the estimate training makes, from the evidence a run gathers ---------------

WRONG_CROWD = "crowd:oracle+mistake,eps_mistake=1,name=wrong+noisy"


def test_a_crowds_member_rows_are_the_estimate_training_makes_of_the_same_answers(monkeypatch):
    """The same sessions stored in training's label store give each member the same
    reliability (the peers' estimator, on answers, second opinions and the orders closure
    checks found implied) as the rows beside the true error rates."""
    crowd = CrowdSettings(overlap=0.2, overlap_until=15, closure_checks=True).source(WRONG_CROWD)
    asked = crowd.ask_session
    sessions: list[tuple[Segments, SessionRecord]] = []

    def recorded(request: SessionRequest) -> tuple[Segments, SessionRecord]:
        segments, record = asked(request)
        sessions.append((segments, record))
        return segments, record

    monkeypatch.setattr(crowd, "ask_session", recorded)
    rng = np.random.default_rng(1)
    _, rows = run_crowd_sessions("sequential", crowd, 20, 8, rng, recheck=None)
    store = LabelStore()
    for session, (pool, record) in enumerate(sessions):
        returns = pool.rewards.sum(axis=1)
        used = tuple(range(len(returns)))
        store.add_session(pool, returns, used, augment(record.answers, returns), session, record)
    assert any(o.implied for _, r in sessions for o in r.crowd.second_opinions)  # (exercised)
    trained = store.reliability()
    assert [row["name"] for row in rows] == list(trained) == ["oracle", "wrong", "noisy"]
    for row in rows:
        found = trained[str(row["name"])]
        expected = {"estimate": found.estimate, "low": found.low, "high": found.high}
        expected |= {"answers": found.answers, "agreement": found.agreement}
        assert {key: row[key] for key in expected} == pytest.approx(expected, abs=1e-9)
        assert row["flagged"] == found.flagged


def test_an_always_wrong_member_is_flagged_and_an_oracle_is_not():
    """A member who reverses every order, beside an oracle and a noisy member: 20 sessions
    of 20 questions, the adaptive overlap as in a run."""
    (cell,) = simulate(["sequential"], [WRONG_CROWD], 20, 20, seed=0)
    rows = {row["name"]: row for row in cell.members}
    assert rows["wrong"]["true_error_rate"] == 1.0 and rows["oracle"]["true_error_rate"] == 0.0
    assert rows["wrong"]["flagged"] and not rows["oracle"]["flagged"]
    assert rows["wrong"]["answers"] >= FLAG_AFTER and rows["wrong"]["estimate"] < FLAG_BELOW


def test_overlap_until_checks_as_many_answers_of_every_member(tmp_path):
    """With no fixed overlap, a member's estimate rests on answers shared with others only
    while the adaptive overlap asks for them: none under 0, at least N under N (here above
    the default of 50, which stops short of it)."""

    def answers(until: int) -> list[int]:
        extra = ["--schemes", "sequential", "--overlap", "0", "--overlap-until", str(until)]
        code, payload = _simulate(tmp_path, "crowd:oracle+mistake+noisy", *extra)
        assert code == 0 and payload["parameters"]["overlap_until"] == until
        return [member["answers"] for member in payload["results"][0]["members"]]

    assert answers(0) == [0, 0, 0]
    assert min(answers(120)) >= 120  # (each member answers about 200 questions)


def test_closure_checks_ask_about_inferred_pairs_of_a_sequential_crowd_only(tmp_path):
    """A pairwise chain infers nothing, so closure checks leave its second opinions on the
    asked pairs (the same answers, the same rows); a sequential chain's change."""
    crowd = "crowd:oracle+mistake,eps_mistake=0.3+noisy"
    members = {}
    for checks in ("0", "1"):
        extra = ["--schemes", "pairwise,sequential", "--closure-checks", checks]
        code, payload = _simulate(tmp_path, crowd, *extra)
        assert code == 0 and payload["parameters"]["closure_checks"] == int(checks)
        members[checks] = {cell["scheme"]: cell["members"] for cell in payload["results"]}
    assert members["0"]["pairwise"] == members["1"]["pairwise"]
    assert members["0"]["sequential"] != members["1"]["sequential"]
