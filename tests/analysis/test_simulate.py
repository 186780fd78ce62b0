from __future__ import annotations

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
