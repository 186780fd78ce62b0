"""The page's state machine: the moves it allows, the survey's run set with its phase,
and readers that never see half a change."""

from __future__ import annotations

import threading

import pytest

from seqrank.labelling.page_state import MOVES, PageState, Phase, PhaseError


def test_done_is_final_and_a_survey_is_left_only_by_its_answer():
    state = PageState()
    state.move(Phase.ASKING, "question 1")
    state.open_survey("root", "root", "survey about the root method")
    with pytest.raises(PhaseError):
        state.move(Phase.ASKING, "question 2")
    state.close_survey()
    assert (state.now().phase, state.now().message) == (
        Phase.WAITING,
        "survey about the root method",
    )
    state.move(Phase.DONE, "thank you")
    for phase in (Phase.WAITING, Phase.ASKING, Phase.TRAINING):
        with pytest.raises(PhaseError):
            state.move(phase, "again")
    with pytest.raises(PhaseError):
        state.open_survey("root", "root", "survey")
    state.move(Phase.DONE, "thank you again")  # a new message only
    assert state.now().message == "thank you again"


def test_nothing_goes_back_to_starting_and_a_survey_needs_its_run():
    assert all(Phase.STARTING not in targets for targets in MOVES.values())
    state = PageState()
    with pytest.raises(PhaseError):
        state.move(Phase.SURVEY, "a survey of no run")
    with pytest.raises(TypeError):
        state.move("training", "a phase named by a string")  # type: ignore[arg-type]
    assert state.now().phase is Phase.STARTING


def test_training_progress_leaves_a_session_that_is_still_asking():
    state = PageState()
    state.move(Phase.ASKING, "question 3")
    state.show_training("the agent is training", still_asking=lambda: True)
    assert state.now().phase is Phase.ASKING
    state.show_training("the agent is training", still_asking=lambda: False)
    assert (state.now().phase, state.now().message) == (Phase.TRAINING, "the agent is training")


def test_readers_see_a_survey_with_its_run_and_a_session_with_its_scheme():
    state, stop, seen = PageState(), threading.Event(), []

    def writer() -> None:
        for k in range(2000):
            state.show_session(f"run{k}", f"scheme{k}", [k])
            state.open_survey(f"run{k}", f"scheme{k}", "survey")
            state.close_survey()
        stop.set()

    thread = threading.Thread(target=writer)
    thread.start()
    while not stop.is_set():
        view = state.now()
        seen.append(view)
        assert (view.phase is Phase.SURVEY) == (view.survey_run is not None)
        assert view.scheme == view.run.replace("run", "scheme")
        assert view.upcoming in ((), (int(view.run[3:]),))
    thread.join()
    assert len(seen) > 10


def test_who_answers_is_chosen_once_before_the_page_asks(tmp_path):
    from seqrank.labelling.crowd_team import open_team
    from seqrank.labelling.db import LabelDB
    from seqrank.labelling.human import Hub, NotATeam, PageSettings

    solo = Hub(LabelDB.in_dir(tmp_path / "solo"), PageSettings())
    with pytest.raises(NotATeam):
        solo.crowd  # noqa: B018 (a person's page has no team)
    solo.state.move(Phase.ASKING, "question 1")
    with pytest.raises(RuntimeError, match="chosen once"):
        open_team(solo, ["alice", "bob"], 0.0, 60.0)
    made = solo.db.rows("SELECT name FROM sqlite_master WHERE name = 'crowd_annotators'")
    assert not made or solo.db.rows("SELECT * FROM crowd_annotators") == []  # nothing stored
    team = Hub(LabelDB.in_dir(tmp_path / "team"), PageSettings())
    open_team(team, ["alice", "bob"], 0.0, 60.0)
    with pytest.raises(RuntimeError, match="chosen once"):
        open_team(team, ["carol"], 0.0, 60.0)
    assert list(team.crowd.tokens) == ["alice", "bob"]
    solo.db.close()
    team.db.close()
