"""`seqrank reward-bench`: pools, one cell, the grid (resumed, never repeated) and scoring
exported labels."""

from __future__ import annotations

import json

import numpy as np
import pytest

from seqrank.cli import main
from seqrank.episodes import Episode
from seqrank.rewardbench.bench import BenchSettings, RewardNet, heldout_measures, run_cell
from seqrank.rewardbench.cells import Cell
from seqrank.rewardbench.grid import read_rows, run_grid
from seqrank.rewardbench.pool import (
    RANDOM_PLAY,
    Pool,
    load_pool,
    pool_from_episodes,
    random_episodes,
    save_pool,
)
from seqrank.rewardbench.summary import (
    format_table,
    summarise,
)
from seqrank.types import Answer

SMALL = BenchSettings(
    budgets=(10, 30),
    session_questions=10,
    segment_length=20,
    heldout_segments=80,
    net=RewardNet(hidden=32, epochs=20),
)


def synthetic_pool(episodes: int = 16, length: int = 100, seed: int = 0) -> Pool:
    """Episodes whose per-step reward is observation feature 0; skill (its mean) rises with
    the episode index, as in a training run."""
    rng = np.random.default_rng(seed)
    obs = rng.normal(size=(episodes, length, 3)).astype(np.float32)
    obs[:, :, 0] += np.linspace(-1.0, 1.0, episodes)[:, None]
    action = rng.uniform(-1, 1, size=(episodes, length, 1)).astype(np.float32)
    trained = [Episode(obs[e], action[e], obs[e, :, 0].copy()) for e in range(episodes)]
    return pool_from_episodes("dmc:cartpole_swingup", trained, 0, [], {"note": "t"})


@pytest.fixture(scope="module")
def pool_file(tmp_path_factory):
    return save_pool(synthetic_pool(), tmp_path_factory.mktemp("pool") / "pool.npz")


def test_a_pool_of_real_episodes_round_trips(tmp_path):
    episodes = random_episodes("dmc:cartpole_swingup", 3, seed=1)
    pool = pool_from_episodes("dmc:cartpole_swingup", episodes[:2], 5, episodes[2:], {"k": 1})
    loaded = load_pool(save_pool(pool, tmp_path / "p.npz"))
    assert loaded.task == "dmc:cartpole_swingup" and loaded.meta == {"k": 1}
    assert loaded.origin.tolist() == [5, 6, RANDOM_PLAY]
    assert loaded.obs.shape == (3, 1000, 5) and loaded.action.shape == (3, 1000, 1)
    np.testing.assert_array_equal(loaded.reward, pool.reward)
    np.testing.assert_allclose(loaded.returns, [e.reward.sum() for e in episodes], rtol=1e-5)


def test_bad_pools_are_named(tmp_path):
    with pytest.raises(ValueError, match="does not exist; build one with"):
        load_pool(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_text("not a pool")
    with pytest.raises(ValueError, match=r"junk\.npz is not a seqrank pool"):
        load_pool(tmp_path / "junk.npz")


def test_the_split_holds_out_every_fourth_episode_by_return():
    train, held = synthetic_pool().split()
    assert len(held) == 4 and len(train) == 12 and not set(train) & set(held)
    # both halves span the skill levels: held-out returns are spread over the whole range
    ranks = np.argsort(np.argsort(synthetic_pool().returns))
    assert sorted(ranks[held].tolist()) == [2, 6, 10, 14]


class _Model:
    def __init__(self, scale: float):
        self.scale = scale

    def member_returns(self, features: np.ndarray) -> np.ndarray:
        return self.scale * features[:, :, 0].sum(1)[None]


def test_held_out_measures_of_a_perfect_and_a_reversed_model():
    pool = synthetic_pool()
    segments = pool.heldout_segments(np.arange(len(pool)), 50, 20)
    perfect, reversed_ = (
        heldout_measures(_Model(1.0), segments),
        heldout_measures(_Model(-1.0), segments),
    )
    top = {"top_accuracy": 1.0, "top_recall": 1.0, "regret": 0.0}
    assert perfect == {"accuracy": 1.0, "spearman": pytest.approx(1.0), **top}
    assert {k: reversed_[k] for k in ("accuracy", "top_accuracy", "top_recall")} == {
        "accuracy": 0.0,
        "top_accuracy": 0.0,
        "top_recall": 0.0,
    }
    assert reversed_["spearman"] == pytest.approx(-1.0) and 0.5 < reversed_["regret"] <= 1.0


def test_a_cell_asks_each_budget_infers_with_sequential_and_repeats_itself():
    pool = synthetic_pool()
    rows = run_cell(pool, Cell("sequential", "oracle", 3), SMALL)
    assert [r["questions"] for r in rows] == [10, 30]
    assert all(r["inferred"] > 0 and r["inferred_wrong"] == 0.0 for r in rows)
    assert rows[-1]["pairs"] == 30 + rows[-1]["inferred"]
    pairwise = run_cell(pool, Cell("pairwise", "oracle", 3), SMALL)
    assert [r["pairs"] for r in pairwise] == [10, 30] and pairwise[0]["inferred_wrong"] is None
    again = run_cell(pool, Cell("sequential", "oracle", 3), SMALL)
    timing = "seconds"
    assert [{k: v for k, v in r.items() if k != timing} for r in again] == [
        {k: v for k, v in r.items() if k != timing} for r in rows
    ]


def test_the_reward_model_learns_the_pool_reward_from_the_scripted_answers():
    """The mean over 4 seeds of the held-out accuracy at 30 questions. Measured over 16
    seeds (tests/learning_thresholds.md): 0.939 to 0.974 per seed, mean 0.957; means of 4
    seeds 0.946 to 0.965. Asserted: above 0.8 (chance is 0.5)."""
    pool = synthetic_pool()
    accuracy = [
        run_cell(pool, Cell("pairwise", "oracle", s), SMALL)[-1]["accuracy"] for s in range(4)
    ]
    assert np.mean(accuracy) > 0.8


def test_the_grid_continues_a_killed_run_without_repeating_a_cell(pool_file, tmp_path):
    out = tmp_path / "grid"
    first = run_grid([pool_file], ["pairwise", "root"], ["oracle"], [0], SMALL, out, 1)
    assert len(first) == 2 * 2 and len(read_rows(out / "rows.jsonl")) == 4
    with (out / "rows.jsonl").open("a") as handle:
        handle.write('{"task": "cut by a ki')  # a kill in the middle of a write
    seen: list[tuple[int, int]] = []
    rows = run_grid(
        [pool_file],
        ["pairwise", "root"],
        ["oracle"],
        [0, 1],
        SMALL,
        out,
        2,
        lambda done, total: seen.append((done, total)),
    )
    assert len(rows) == 8 and seen[0] == (2, 4) and seen[-1] == (4, 4)
    assert read_rows(out / "rows.jsonl")[:4] == first  # the finished cells were kept as they were
    other = BenchSettings(budgets=(10,), session_questions=10, segment_length=20)
    with pytest.raises(
        ValueError, match=r"other settings \(budgets, heldout_segments, net differ\)"
    ):
        run_grid([pool_file], ["pairwise"], ["oracle"], [0], other, out, 1)


def test_the_grid_runs_seed_by_seed(pool_file, tmp_path):
    """Every combination's seed 0 before any seed 1: a grid stopped part way leaves the
    combinations with the same seeds, so its partial table compares like with like."""
    out = tmp_path / "grid"
    run_grid([pool_file], ["pairwise"], ["oracle", "mistake"], [0, 1], SMALL, out, 1)
    order = [(r["seed"], r["teacher"]) for r in read_rows(out / "rows.jsonl")][::2]
    assert order == [(0, "oracle"), (0, "mistake"), (1, "oracle"), (1, "mistake")]


@pytest.mark.parametrize("learner", ["surf", "rime"])
def test_a_cell_learns_with_each_learner_and_repeats_itself(learner):
    """Each learner's cell fits and scores at every budget, its measures in the row; the
    same cell twice gives the same rows. (Above chance: each learner learns the reward.)"""
    cell = Cell("sequential", "oracle", 1, learner)
    rows = run_cell(synthetic_pool(), cell, SMALL)
    assert [r["questions"] for r in rows] == [10, 30]
    assert all(r["learner"] == learner for r in rows) and rows[-1]["accuracy"] > 0.6
    # each row keeps what its fit did: epochs, and the learner's own measures
    assert all(1 <= r["epochs"] <= SMALL.net.epochs for r in rows)
    assert any(key.startswith(f"{learner}_") for key in rows[-1])
    if learner == "surf":  # 10 unlabelled pairs per question asked so far
        assert [r["surf_unlabelled_pairs"] for r in rows] == [100, 300]
    else:  # a RIME fit runs its 17 epochs at least (of at most SMALL's 20)
        assert all(r["epochs"] >= 17 for r in rows)
    again = run_cell(synthetic_pool(), cell, SMALL)
    assert [r["accuracy"] for r in again] == [r["accuracy"] for r in rows]


def test_the_grid_has_a_learner_axis_and_rows_before_it_count_as_plain(pool_file, tmp_path):
    out = tmp_path / "grid"
    learners = ("plain", "surf", "rime")
    rows = run_grid([pool_file], ["root"], ["oracle"], [0], SMALL, out, 2, learners=learners)
    assert sorted({r["learner"] for r in rows}) == sorted(learners) and len(rows) == 3 * 2
    # a grid written before the axis: its rows have no learner, and stand for plain
    old = [{k: v for k, v in r.items() if k != "learner"} for r in rows if r["learner"] == "plain"]
    (out / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in old))
    seen: list[tuple[int, int]] = []
    again = run_grid(
        [pool_file],
        ["root"],
        ["oracle"],
        [0],
        SMALL,
        out,
        1,
        lambda done, total: seen.append((done, total)),
        learners=["plain"],
    )
    assert again == old and seen == [(1, 1)]  # nothing run again
    table = format_table(summarise(rows))
    assert "| oracle | surf | 30 | root |" in table and "| oracle | rime | 30 | root |" in table


def test_the_command_runs_the_grid_and_prints_the_table(pool_file, tmp_path, capsys):
    out = tmp_path / "bench"
    args = ["reward-bench", "run", "--pool", str(pool_file), "--schemes", "pairwise,root"]
    args += ["--seeds", "1", "--budgets", "10", "--session-questions", "10", "--out", str(out)]
    assert main([*args, "--heldout-segments", "40", "--reward-epochs", "3", "--workers", "1"]) == 0
    printed, logged = capsys.readouterr()
    assert "| dmc:cartpole_swingup | oracle | plain | 10 | pairwise | 1 |" in printed
    # not a terminal: a line per finished cell instead of a live bar
    assert "cells 0/2 (" in logged and "cells 1/2 (" in logged and "cells 2/2 (" in logged
    assert "no other method shares a cell with plain" in printed
    assert not (out / "effects.md").exists()
    # another method beside plain: each is compared with plain, seed by seed
    assert (
        main(
            [
                *args,
                "--heldout-segments",
                "40",
                "--reward-epochs",
                "3",
                "--workers",
                "1",
                "--augments",
                "full,checked",
            ]
        )
        == 0
    )
    assert "each method against plain, seed by seed" in capsys.readouterr().out
    assert "| plain+checked vs plain | root | 10 | 1 |" in (out / "effects.md").read_text()
    assert (out / "curves_dmc-cartpole_swingup.png").read_bytes()[:4] == b"\x89PNG"
    assert main(["reward-bench", "run", "--pool", str(tmp_path / "none.npz")]) == 2
    assert "does not exist; build one with" in capsys.readouterr().err


def test_a_teacher_keeps_its_knobs_in_the_teacher_list():
    from seqrank.cli.reward_bench import teacher_list

    assert teacher_list("mistake,eps_mistake=0.2,oracle") == ["mistake,eps_mistake=0.2", "oracle"]
    assert teacher_list("beta=1,gamma=0.95") == ["beta=1,gamma=0.95"]
    assert teacher_list("oracle, noisy") == ["oracle", "noisy"]
    # ';' separates what commas cannot: knobs alone, after another teacher
    assert teacher_list("oracle;beta=1,gamma=0.95") == ["oracle", "beta=1,gamma=0.95"]


@pytest.mark.parametrize(
    ("teacher", "said", "not_said"),
    [
        ("bogus", "unknown teacher 'bogus'; accepted: oracle, mistake", "human"),
        ("human", "the grid asks scripted teachers only", "unknown"),
        ("replay:labels.jsonl", "are scored with `seqrank reward-bench score`", "unknown"),
    ],
)
def test_the_grid_names_a_bad_teacher_and_offers_only_scripted_ones(
    pool_file, tmp_path, capsys, teacher, said, not_said
):
    args = ["reward-bench", "run", "--pool", str(pool_file), "--teachers", teacher]
    assert main([*args, "--out", str(tmp_path / "grid")]) == 2
    error = capsys.readouterr().err
    assert said in error and not_said not in error
    assert not (tmp_path / "grid").exists()


def test_a_grid_folder_refuses_another_pool_of_the_same_task(pool_file, tmp_path):
    out = tmp_path / "grid"
    run_grid([pool_file], ["pairwise"], ["oracle"], [0], SMALL, out, 1)
    other = save_pool(synthetic_pool(seed=1), tmp_path / "other.npz")
    with pytest.raises(ValueError, match=r"holds dmc:cartpole_swingup rows of another pool"):
        run_grid([other], ["pairwise"], ["oracle"], [0], SMALL, out, 1)
    with pytest.raises(ValueError, match="one pool per task"):
        run_grid([pool_file, other], ["pairwise"], ["oracle"], [0], SMALL, tmp_path / "two", 1)
    moved = tmp_path / "moved.npz"  # the same pool under another name is the same pool
    moved.write_bytes(pool_file.read_bytes())
    assert len(run_grid([moved], ["pairwise"], ["oracle"], [0], SMALL, out, 1)) == 2


def test_exported_labels_are_scored_on_a_pool(pool_file, tmp_path, capsys):
    """A label file (the labelling page's JSONL): one sequential session answered by the
    true returns, scored after its session."""
    pool = load_pool(pool_file)
    lines = [
        {
            "type": "header",
            "format": "seqrank-labels",
            "version": 1,
            "task": pool.task,
            "obs_dim": 3,
            "act_dim": 1,
            "segment_length": 20,
        }
    ]
    segments = pool.store(np.arange(len(pool))).sample_segments(9, 20, np.random.default_rng(0))
    for k in range(9):
        lines.append(
            {
                "type": "segment",
                "id": f"r/0/{k}",
                "run": "r",
                "session": 0,
                "features": segments.features[k].tolist(),
                "rewards": segments.rewards[k].tolist(),
                "states": None,
                "context": None,
            }
        )
    returns, defender = segments.rewards.sum(1), 0
    for k in range(1, 9):
        answer = "first" if returns[defender] > returns[k] else "second"
        lines.append(
            {
                "type": "answer",
                "run": "r",
                "scheme": "sequential",
                "session": 0,
                "index": k - 1,
                "first": f"r/0/{defender}",
                "second": f"r/0/{k}",
                "defender": f"r/0/{defender}",
                "answer": answer,
            }
        )
        defender = k
    path = tmp_path / "labels.jsonl"
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    assert main(["reward-bench", "score", str(path), "--pool", str(pool_file)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("    8 answers,") and "wrong inferred 0.000" in printed
    for task, code in (("cartpole_swingup", 0), ("dmc:walker_walk", 2)):  # spelled otherwise
        lines[0]["task"] = task
        path.write_text("".join(json.dumps(line) + "\n" for line in lines))
        assert main(["reward-bench", "score", str(path), "--pool", str(pool_file)]) == code
    assert "was recorded on dmc:walker_walk, not dmc:cartpole_swingup" in capsys.readouterr().err


def test_the_grid_has_an_augment_axis_that_re_checks_under_a_noisy_teacher(pool_file, tmp_path):
    out = tmp_path / "checked"
    augments = ("full", "checked")
    rows = run_grid([pool_file], ["root"], ["mistake"], [0, 1], SMALL, out, 2, augments=augments)
    by_augment = {a: [r for r in rows if r["augment"] == a] for a in augments}
    assert all(len(v) == 2 * 2 for v in by_augment.values())  # 2 seeds x 2 budgets
    assert all(r["asked_wrong"] is not None for r in rows)
    # re-checks spend questions: fewer distinct pairs are asked, and fewer are inferred
    full_inferred = sum(r["inferred"] for r in by_augment["full"])
    assert sum(r["inferred"] for r in by_augment["checked"]) < full_inferred
    table = format_table(summarise(rows))
    assert (
        "| mistake | plain+checked | 30 | root |" in table and "| mistake | plain | 30 |" in table
    )


def test_a_pool_can_take_the_first_part_of_a_longer_run(tmp_path, capsys):
    """`--until-step`: the episodes that ended by a step, as a shorter run of the same
    settings would have kept them."""
    from seqrank.rewardbench.pool import pool_from_run
    from support.runs import run, tiny_config

    config = tiny_config(reward="true", steps=3000, unsup_steps=0, eval_every=3000)
    run(tmp_path / "run", config)
    whole = pool_from_run(tmp_path / "run", 0, 0)
    part = pool_from_run(tmp_path / "run", 1, 0, until_step=2500)
    assert len(whole) == 3 and part.origin.tolist() == [0, 1, RANDOM_PLAY]
    np.testing.assert_array_equal(part.obs[:2], whole.obs[:2])
    assert part.meta["run_steps"] == 2000
    with pytest.raises(ValueError, match=r"no episode of run .* ended by step 999"):
        pool_from_run(tmp_path / "run", 0, 0, until_step=999)
    with pytest.raises(ValueError, match="--until-step 3001 is past the run's last step"):
        pool_from_run(tmp_path / "run", 0, 0, until_step=3001)
    code = main(["reward-bench", "pool", "--until-step", "2000", "--out", str(tmp_path / "p")])
    assert code == 2
    assert "--until-step takes part of a run given with --from-run" in capsys.readouterr().err
    assert part.meta["until_step"] == 2500 and whole.meta["until_step"] is None


class _SlipsOnRepeats:
    """Answers by the segments' true returns, except that every repeat disagrees; keeps
    what each session was told about the teacher."""

    def __init__(self) -> None:
        self.told: list[bool] = []  # per session: the teacher contradicted themselves before
        self.slipped: list[bool] = []  # per session: a repeat was asked (and disagreed)
        self.model: list[int] = []  # per session: how many segments the model judged

    def has_session(self, session: int) -> bool:
        return True

    def check_compatible(self, task: str, obs_dim: int, act_dim: int) -> None:
        pass

    def ask_session(self, request):
        self.told.append(request.recheck.contradicted)
        judged = request.recheck.model_returns
        self.model.append(0 if judged is None else len(judged))
        returns = request.segments.rewards.sum(axis=1)
        asked: set[tuple[int, int]] = set()

        def ask(first: int, second: int) -> Answer:
            truth = Answer.FIRST if returns[first] > returns[second] else Answer.SECOND
            repeat = (first, second) in asked
            asked.add((first, second))
            return truth.flipped() if repeat else truth

        record = request.run_scheme(ask)
        self.slipped.append(len(set(asked)) < len(record.answers))
        return request.segments, record


def test_a_checked_cell_tells_each_session_whether_the_teacher_contradicted_themselves():
    source = _SlipsOnRepeats()
    run_cell(synthetic_pool(), Cell("root", "oracle", 1, augment="checked"), SMALL, source)
    # once a session's repeat disagreed, every later session is told (the first session,
    # with no model to agree, asks a win again: seed 1 draws one that implies pairs)
    assert source.slipped[0]
    assert source.told == [any(source.slipped[:k]) for k in range(len(source.told))]
    # the model gives its opinion on every segment from its first fit on (10 questions)
    assert source.model[0] == 0 and all(n == source.model[1] > 0 for n in source.model[1:])


def test_a_scripted_teachers_cells_run_once_beside_a_crowd_under_two_weightings(
    pool_file, tmp_path, capsys
):
    out = tmp_path / "bench"
    args = ["reward-bench", "run", "--pool", str(pool_file), "--schemes", "root"]
    args += ["--teachers", "crowd:oracle+mistake+noisy,oracle", "--weightings", "reliability,none"]
    args += ["--seeds", "1", "--budgets", "10", "--session-questions", "10", "--out", str(out)]
    assert main([*args, "--heldout-segments", "40", "--reward-epochs", "3", "--workers", "1"]) == 0
    printed, logged = capsys.readouterr()
    assert "cells 3/3 (" in logged  # the crowd under each weighting, the oracle once
    rows = read_rows(out / "rows.jsonl")
    assert sorted(r["teacher"] for r in rows).count("oracle") == 1
    assert "| dmc:cartpole_swingup | oracle | plain | 10 | root | 1 |" in printed
    # the crowd's default (labels as answered) is the baseline; weighting is the variant
    effects = (out / "effects.md").read_text()
    assert "| plain+weighted vs plain | root | 10 | 1 |" in effects
    # a folder written before the fix holds the oracle's row twice: reported once
    oracle = next(r for r in rows if r["teacher"] == "oracle")
    with (out / "rows.jsonl").open("a") as handle:
        handle.write(json.dumps({**oracle, "weighting": "none"}) + "\n")
    assert main(["reward-bench", "report", str(out)]) == 0
    assert "| dmc:cartpole_swingup | oracle | plain | 10 | root | 1 |" in capsys.readouterr().out
