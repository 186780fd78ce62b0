"""`seqrank dataset make` and `load_dataset` at their edges: tasks without MuJoCo state,
tasks seqrank cannot play, source shares, non-finite values, foreign action bounds and
the messages of datasets that cannot be read or labelled."""

from __future__ import annotations

from seqrank.cli import main
from seqrank.offline.minari_io import episodes_with_states, load_dataset


def refusal(capsys, *args: str) -> str:
    """The one line a refused command prints (exit code 2)."""
    code = main(list(args))
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    return err


def test_random_play_on_a_task_without_mujoco_state_keeps_no_states(tmp_path, capsys):
    out = tmp_path / "pendulum"
    code = main(["dataset", "make", "--task", "gym:Pendulum-v1", "--source", "random",
                 "--episodes", "2", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    dataset = load_dataset(out)
    assert dataset.episode_count == 2 and dataset.act_dim == 1
    try:
        episodes_with_states(out)
    except ValueError as problem:
        assert "no physics states" in str(problem)
    else:
        raise AssertionError("a dataset without states was taken for labelling")


def test_a_task_with_discrete_actions_is_refused_in_one_line_leaving_nothing(tmp_path, capsys):
    out = tmp_path / "cartpole"
    err = refusal(capsys, "dataset", "make", "--task", "gym:CartPole-v1", "--source",
                  "random", "--episodes", "2", "--out", str(out))  # fmt: skip
    assert "Discrete(2)" in err and "Box" in err
    assert not out.exists()
