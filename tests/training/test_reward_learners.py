"""Short runs with each reward learner beyond the paper (SURF, RIME with its warm start):
they train, log what the learner did per session, and a killed run resumed from its
checkpoint ends with the same numbers as an uninterrupted one."""

from __future__ import annotations

import pytest
import torch

from seqrank.config import resolve_config
from support.runs import resume_after_kill, run, tiny_config, without_timing

SHORT = dict(steps=2200, feedback_frequency=400, eval_every=1100, checkpoint_every=1000)
CASES = {  # (settings, kill at, checkpoint resumed from)
    # SURF on MRN's backbone, the reference path; a threshold the tiny model reaches
    "surf": (
        dict(**SHORT, reward_learner="surf", surf_threshold=0.6, backbone="mrn", path="reference"),
        1700,
        1000,
    ),
    # RIME with its warm start on the fast path (run here on the CPU), resumed after its
    # first two sessions (1200, 1700): the restored selection state must carry on as it was
    # (a fit here runs at most 5 epochs, and at least 3)
    "rime": (
        dict(reward_learner="rime", rime_min_epochs=3, warm_start=1, path="fast", steps=2400),
        2100,
        2000,
    ),
}


@pytest.mark.parametrize("name", CASES)
def test_a_run_with_the_learner_trains_logs_it_and_resumes_exactly(name, tmp_path):
    settings, kill_at, checkpoint = CASES[name]
    config = tiny_config(**settings)
    finished = run(tmp_path / "finished", config)
    sessions = [r for r in finished.run_dir.read_metrics() if r["kind"] == "feedback"]
    assert len(sessions) == 3
    # the summary says which update the run took: these cases name the path, in fp32
    summary = finished.run_dir.read_summary()
    assert (summary["update_path"], summary["precision"]) == (settings["path"], "fp32")
    if name == "surf":
        # 10 per question asked so far: 10 questions a session
        assert [r["surf_unlabelled_pairs"] for r in sessions] == [100, 200, 300]
        assert sum(r["surf_pseudo_labels"] for r in sessions) > 0
    else:
        assert all(r["rime_kept"] + r["rime_flipped"] + r["rime_dropped"] > 0 for r in sessions)
        assert sessions[-1]["rime_beta"] < 3.0  # the uncertainty weight decays
        assert all(3 <= r["reward_epochs"] <= 5 for r in sessions)
    resumed, state = resume_after_kill(tmp_path, config, kill_at, checkpoint)
    if name == "rime":
        assert state["reward_learner"]["updates"] > 0 and state["reward_learner"]["rho"] > 0
    assert without_timing(resumed.run_dir.read_metrics()) == without_timing(
        finished.run_dir.read_metrics()
    )
    for a, b in zip(
        resumed.reward_model.net.parameters(), finished.reward_model.net.parameters(), strict=True
    ):
        assert torch.equal(a, b)
    assert resumed.reward.learner.state_dict() == finished.reward.learner.state_dict()


def test_the_warm_start_changes_the_reward_model_before_the_first_session(tmp_path):
    """Pre-training alone (no session yet): with warm_start the reward model has moved."""
    settings = dict(steps=1100, eval_every=1100, max_feedback=10, feedback_frequency=2000)
    plain = run(tmp_path / "plain", tiny_config(**settings, unsup_steps=700, seed_steps=300))
    warm = run(
        tmp_path / "warm", tiny_config(**settings, unsup_steps=700, seed_steps=300, warm_start=1)
    )
    moved = [
        not torch.equal(a, b)
        for a, b in zip(
            plain.reward_model.net.parameters(), warm.reward_model.net.parameters(), strict=True
        )
    ]
    assert all(moved)


def test_the_learner_settings_are_sweep_and_config_fields():
    config = resolve_config(
        "dmc:cartpole_swingup", "small", {"reward_learner": "rime", "rime_beta_min": 0.5}
    )
    assert config.reward_learner == "rime" and config.as_dict()["rime_beta_min"] == 0.5
    with pytest.raises(
        ValueError, match="unknown reward_learner 'best'; accepted: plain, surf, rime"
    ):
        resolve_config("dmc:cartpole_swingup", "small", {"reward_learner": "best"})
    # RIME's own values per suite: DMControl 17 epochs at least and beta over 60 epochs,
    # Meta-World 7 and 600 (`run_parallel.sh`, `train_RIME.py`)
    metaworld = resolve_config("button-press-v3", "small", {"reward_learner": "rime"})
    assert (config.rime_min_epochs, config.rime_decay_updates) == (17, 60)
    assert (metaworld.rime_min_epochs, metaworld.rime_decay_updates) == (7, 600)
