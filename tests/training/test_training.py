"""End-to-end training on a tiny configuration (CPU, seconds)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

from support.runs import resume_after_kill, run, tiny_config, without_timing


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    path = tmp_path_factory.mktemp("runs") / "full"
    return run(path, tiny_config())


def test_smoke_run_gets_through_every_phase(finished):
    rows = finished.run_dir.read_metrics()
    feedback = [r for r in rows if r["kind"] == "feedback"]
    evals = [r for r in rows if r["kind"] == "eval"]
    assert [r["step"] for r in feedback] == [1200, 1700, 2200]
    assert [r["step"] for r in evals] == [1600, 3200]
    assert feedback[-1]["total_asked"] == 30
    assert finished.pretraining.stats.count > 0  # pre-training used the state-entropy reward
    assert finished.agent.updates >= 3200 - 300
    assert all(0 <= r["reward_heldout_accuracy"] <= 1 for r in feedback)
    assert feedback[0]["pairs_per_question"] >= 1
    summary = (finished.run_dir.path / "summary.json").read_text()
    assert '"asked": 30' in summary


def tensorboard_events(directory):
    accumulator = EventAccumulator(str(directory))
    accumulator.Reload()
    return {name: accumulator.Scalars(name) for name in accumulator.Tags()["scalars"]}


def test_every_run_writes_tensorboard_events_matching_its_metrics(finished):
    rows = finished.run_dir.read_metrics()
    events = tensorboard_events(finished.run_dir.path)
    evals = [r for r in rows if r["kind"] == "eval"]
    assert [(e.step, e.value) for e in events["eval/return"]] == [
        (r["step"], pytest.approx(r["eval_return"])) for r in evals
    ]
    feedback = [r for r in rows if r["kind"] == "feedback"]
    assert [e.step for e in events["feedback/pairs_per_question"]] == [r["step"] for r in feedback]
    assert "reward/heldout_accuracy" in events and "losses/critic" in events


def test_same_seed_same_metrics(finished, tmp_path):
    again = run(tmp_path / "again", tiny_config())
    assert without_timing(again.run_dir.read_metrics()) == without_timing(
        finished.run_dir.read_metrics()
    )
    for a, b in zip(again.agent.actor.parameters(), finished.agent.actor.parameters(), strict=True):
        assert torch.equal(a, b)


def test_different_seed_different_metrics(finished, tmp_path):
    """Through pre-training and the first session (seeds part at once; the rest of the run
    would only repeat that)."""
    config = tiny_config(seed=4, steps=1300, max_feedback=10, eval_every=1300)
    other = without_timing(run(tmp_path / "other", config).run_dir.read_metrics())
    first = without_timing(finished.run_dir.read_metrics())
    assert len(other) == 3 and [r["kind"] for r in first[:2]] == [r["kind"] for r in other[:2]]
    assert other[:2] != first[:2]  # the step-1000 train row and the first session's row


def test_resumed_run_ends_with_the_same_numbers(finished, tmp_path):
    resumed, _ = resume_after_kill(tmp_path, tiny_config())
    assert without_timing(resumed.run_dir.read_metrics()) == without_timing(
        finished.run_dir.read_metrics()
    )
    for a, b in zip(
        resumed.agent.critic.parameters(), finished.agent.critic.parameters(), strict=True
    ):
        assert torch.equal(a, b)
    # TensorBoard dropped the events after the checkpoint too: each step once
    steps = [e.step for e in tensorboard_events(resumed.run_dir.path)["losses/critic"]]
    rows = resumed.run_dir.read_metrics()
    assert steps == [r["step"] for r in rows if r["kind"] == "train"]


def test_mrn_backbone_with_equal_labels(tmp_path):
    trainer = run(
        tmp_path / "mrn",
        tiny_config(
            backbone="mrn",
            teacher="equal",
            meta_update_frequency=100,
            steps=2400,
            max_feedback=20,
            eval_every=2400,
        ),
    )
    assert "meta_outer_loss" in trainer.counters.extra
    assert trainer.counters.asked == 20


@pytest.mark.parametrize("scheme", ["pairwise", "root", "ranked"])
def test_every_scheme_trains_with_informative_selection(tmp_path, scheme):
    trainer = run(
        tmp_path / scheme,
        tiny_config(
            scheme=scheme, selection="entropy", steps=2000, max_feedback=20, eval_every=2000
        ),
    )
    assert trainer.counters.asked == 20 and trainer.counters.sessions == 2


def test_recorded_states_let_a_labelled_segment_be_rendered_again(tmp_path):
    trainer = run(
        tmp_path / "states",
        tiny_config(record_states=1, steps=1700, max_feedback=10, eval_every=1700),
    )
    labels = trainer.labels
    assert len(labels.segment_states) == len(labels.segments) > 0
    states = labels.segment_states[0]
    assert states is not None and states.shape[0] == trainer.config.segment_length
    frames = trainer.env.render_states(states, labels.segment_contexts[0], 32, 32)
    assert frames.shape == (trainer.config.segment_length, 32, 32, 3)
    assert not (frames[0] == frames[-1]).all()  # the clip moves
    trainer.env.set_state(states[7])
    assert (trainer.env.get_state() == states[7]).all()


def test_a_checked_run_asks_big_moves_again_and_stores_each_answer(tmp_path):
    trainer = run(
        tmp_path / "checked",
        tiny_config(
            scheme="root",
            teacher="mistake",
            augment="checked",
            steps=2000,
            max_feedback=20,
            eval_every=2000,
        ),
    )
    asked = trainer.labels.asked
    assert trainer.counters.asked == len(asked) == 20  # repeats spend the budget
    pairs = [frozenset((first, second)) for _, _, first, second, _, _ in asked]
    assert len(set(pairs)) < len(pairs)  # some answer was asked again
    assert sum(not inferred for inferred in trainer.labels.inferred) == 20  # each answer kept
    # the next session learns from the stored answers whether the teacher contradicted
    # themselves (then big answers are asked twice more)
    erred = trainer.labels.teacher_contradicted()
    assert trainer.sessions._request(trainer.counters, False).recheck.contradicted is erred
    trainer.labels.asked += [(9, "root", 0, 1, "first", True), (9, "root", 0, 1, "second", True)]
    later = trainer.sessions._request(trainer.counters, False)
    assert later.recheck.contradicted
    # after the first session the fitted model judges each segment (its second opinion)
    features = later.segments.features
    expected = trainer.reward_model.member_returns(features).mean(axis=0)
    assert np.allclose(later.recheck.model_returns, expected)
    assert trainer.sessions._request(trainer.counters, True).recheck.model_returns is None
