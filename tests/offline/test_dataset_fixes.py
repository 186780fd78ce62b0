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


def test_sources_without_a_share_split_what_the_shares_leave():
    from seqrank.offline.sources import episode_counts, parse_source

    def counts(*texts: str, episodes: int = 10) -> list[int]:
        return episode_counts([parse_source(t) for t in texts], episodes)

    assert counts("scripted=0.7", "random") == [7, 3]
    assert counts("scripted=0.5", "random", "scripted:0.3") == [5, 3, 2]  # ties in order
    assert counts("scripted=0.1", "random=0.2", "scripted:0.3=0.7") == [1, 2, 7]
    assert counts("random", "scripted") == [5, 5]
    for texts, why in (
        (("scripted=0.7", "random=0.5"), "0.7 + 0.5 = 1.2, more than 1"),
        (("scripted=0.7", "random=0.3", "scripted:0"), "leaving nothing"),
        (("scripted=0.4", "random=0.3"), "less than 1, and no source without a share"),
    ):
        try:
            counts(*texts)
        except ValueError as problem:
            assert why in str(problem) and "accepted: shares" in str(problem), problem
        else:
            raise AssertionError(f"{texts} were taken")


def test_shares_that_do_not_add_up_are_refused_by_dataset_make(tmp_path, capsys):
    err = refusal(capsys, "dataset", "make", "--task", "dmc:cartpole_swingup", "--source",
                  "random=0.4", "--source", "random=0.3", "--episodes", "10",
                  "--out", str(tmp_path / "d"))  # fmt: skip
    assert "0.4 + 0.3 = 0.7, less than 1" in err and not (tmp_path / "d").exists()
