"""`seqrank report`: statistics against hand-computed values, tables from run folders."""

from __future__ import annotations

import json

import numpy as np
import pytest

from seqrank.cli import main
from seqrank.report.stats import (
    iqm,
    pooled_iqm,
    probability_of_improvement,
    stratified_bootstrap_ci,
)


def test_iqm_is_the_mean_of_the_middle_half():
    assert iqm(np.arange(1, 9)) == pytest.approx(4.5)  # mean of 3, 4, 5, 6
    assert iqm(np.array([100.0, 1, 2, 3])) == pytest.approx(2.5)  # 1 and 100 trimmed
    assert pooled_iqm({"a": np.array([1.0, 2]), "b": np.array([3.0, 4])}) == pytest.approx(2.5)


def test_probability_of_improvement_by_hand():
    x, y = {"t": np.array([1.0, 2, 3])}, {"t": np.array([0.0, 2, 5])}
    # wins: 1>0; 2>0; 2=2 (half); 3>0; 3>2 -> 4.5 of 9 pairs
    assert probability_of_improvement(x, y) == pytest.approx(0.5)
    x2 = {"t": np.array([1.0, 2, 3]), "u": np.array([5.0])}
    y2 = {"t": np.array([0.0, 2, 5]), "u": np.array([4.0])}
    assert probability_of_improvement(x2, y2) == pytest.approx((0.5 + 1.0) / 2)
    with pytest.raises(ValueError, match="no task"):
        probability_of_improvement({"t": np.ones(2)}, {"u": np.ones(2)})


def test_stratified_bootstrap_resamples_within_tasks():
    rng = np.random.default_rng(0)
    constant = {"a": np.full(5, 2.0), "b": np.full(3, 7.0)}
    # every resample keeps 5 twos and 3 sevens: the statistic cannot move
    assert stratified_bootstrap_ci(pooled_iqm, (constant,), 200, rng) == (
        pytest.approx(pooled_iqm(constant)),
        pytest.approx(pooled_iqm(constant)),
    )
    spread = {"a": np.arange(10.0)}
    low, high = stratified_bootstrap_ci(pooled_iqm, (spread,), 2000, rng)
    assert low < iqm(spread["a"]) < high and low > 2.0 and high < 7.0


def fake_run(
    directory,
    task,
    scheme,
    seed,
    returns,
    success=None,
    finished=True,
    reward="learned",
    **settings,
):
    directory.mkdir(parents=True)
    config = {"task": task, "scheme": scheme, "backbone": "pebble", "teacher": "oracle"}
    config["reward"] = reward
    config.update(seed=seed, steps=2000, scale="small", **settings)
    (directory / "config.json").write_text(json.dumps(config))
    rows = []
    for k, value in enumerate(returns):
        rows.append(
            {
                "step": 1000 * (k + 1),
                "kind": "eval",
                "eval_return": value,
                "eval_success_rate": (success or [0.0] * len(returns))[k],
            }
        )
        rows.append(
            {
                "step": 1000 * (k + 1),
                "kind": "feedback",
                "total_asked": 10 * (k + 1),
                "total_pairs": (14 if scheme == "root" else 10) * (k + 1),
                "reward_heldout_accuracy": 0.7,
            }
        )
    (directory / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    if finished:
        (directory / "summary.json").write_text(json.dumps({"final_eval_return": returns[-1]}))


def test_report_tables_match_the_runs(tmp_path):
    finals = {"pairwise": [300.0, 340.0, 320.0], "root": [400.0, 380.0, 450.0]}
    for scheme, values in finals.items():
        for seed, value in enumerate(values):
            fake_run(
                tmp_path / "walker" / f"{scheme}_{seed}",
                "walker_walk",
                scheme,
                seed,
                [100.0, value],
            )
    fake_run(tmp_path / "door" / "root_0", "door-open", "root", 0, [1.0, 2.0], [0.0, 60.0])
    fake_run(tmp_path / "door" / "root_1", "door-open", "root", 1, [1.0], [40.0], finished=False)
    fake_run(tmp_path / "door" / "pairwise_0", "door-open", "pairwise", 0, [1.0, 2.0], [0.0, 20.0])
    argv = ["report", str(tmp_path), "--bootstrap", "300", "--out", str(tmp_path / "r")]
    assert main([*argv, "--include-unfinished"]) == 0
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    cells = {(c["task"], c["method"]): c for c in report["table"]}
    walker_root = cells[("walker_walk", "root")]
    assert walker_root["mean"] == pytest.approx(np.mean(finals["root"]))
    assert walker_root["std"] == pytest.approx(np.std(finals["root"], ddof=1))
    assert walker_root["metric"] == "return" and walker_root["n"] == 3
    door_root = cells[("door-open", "root")]  # success rates; one run still going
    assert door_root["metric"] == "success" and door_root["mean"] == pytest.approx(50.0)
    assert door_root["partial"] == 1 and door_root["steps"] == 1000
    # root beats pairwise in every walker pair and in both door pairs: P = 1
    pi = {(p["x"], p["y"]): p["p"] for p in report["probability_of_improvement"]}
    assert pi[("root", "pairwise")] == pytest.approx(1.0)
    assert pi[("pairwise", "root")] == pytest.approx(0.0)
    aggregate = {a["method"]: a["iqm"] for a in report["aggregate_iqm"]}
    normalized_root = sorted([0.4, 0.38, 0.45, 0.6, 0.4])  # returns / 1000, success / 100
    assert aggregate["root"] == pytest.approx(
        np.mean(normalized_root[1:4])
    )  # scipy trims int(0.25 * 5) = 1 each side
    text = (tmp_path / "r" / "report.md").read_text()
    assert "| walker_walk | 320.0 ± 20.0 (n=3) | 410.0 ± 36.1 (n=3) |" in text
    for name in ("curves_walker_walk.png", "curves_door-open.png", "feedback_door-open.png"):
        assert (tmp_path / "r" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "r" / "report.csv").read_text().count("\n") == 1 + 4


def test_report_of_an_empty_folder_is_a_clear_error(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    assert "holds no run directories" in capsys.readouterr().err


def test_the_true_reward_agent_is_a_column_a_reference_and_the_unit_of_relative_scores(
    tmp_path,
):
    finals = {"root": [300.0, 360.0, 330.0], "true-reward": [600.0, 600.0, 600.0]}
    for method, values in finals.items():
        reward = "true" if method == "true-reward" else "learned"
        for seed, value in enumerate(values):
            path = tmp_path / f"{method}_{seed}"
            fake_run(
                path,
                "walker_walk",
                "sequential" if reward == "true" else method,
                seed,
                [100.0, value],
                reward=reward,
            )
    fake_run(tmp_path / "floor_0", "walker_walk", "sequential", 0, [50.0, 60.0], reward="none")
    fake_run(tmp_path / "mistake_0", "walker_walk", "root", 0, [50.0, 90.0])
    (tmp_path / "mistake_0" / "config.json").write_text(
        (tmp_path / "mistake_0" / "config.json").read_text().replace("oracle", "mistake")
    )
    assert main(["report", str(tmp_path), "--bootstrap", "300", "--out", str(tmp_path / "r")]) == 0
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    # baselines are named by what they learn from, last; the teacher joins learned names only
    assert report["methods"] == ["root/mistake", "root/oracle", "no-feedback", "true-reward"]
    assert report["reference"] == "true-reward"
    cells = {c["method"]: c for c in report["table"]}
    assert cells["root/oracle"]["relative"] == pytest.approx(330.0 / 600.0)
    # the reference is constant: the interval lies within the root runs' range over 600
    low, high = cells["root/oracle"]["relative_low"], cells["root/oracle"]["relative_high"]
    assert 300.0 / 600.0 <= low < 330.0 / 600.0 < high <= 360.0 / 600.0
    assert cells["no-feedback"]["relative"] == pytest.approx(0.1)
    assert cells["true-reward"]["relative"] is None
    text = (tmp_path / "r" / "report.md").read_text()
    assert "| walker_walk | root/oracle | 0.55 |" in text
    header = next(line for line in text.splitlines() if line.startswith("| task |"))
    assert header.endswith("| no-feedback | true-reward |")  # columns of the main table
    csv_text = (tmp_path / "r" / "report.csv").read_text()
    assert csv_text.splitlines()[0].endswith("relative,relative_low,relative_high")


def test_every_curve_draws_the_true_reward_agent_as_a_dashed_black_reference(tmp_path, monkeypatch):
    from seqrank.report import plots

    for seed, (mid, end) in enumerate([(400.0, 600.0), (500.0, 700.0)]):
        fake_run(
            tmp_path / f"true_{seed}", "walker_walk", "sequential", seed, [mid, end], reward="true"
        )
        fake_run(tmp_path / f"root_{seed}", "walker_walk", "root", seed, [100.0, 200.0 + seed])
    figures = []
    monkeypatch.setattr(plots.plt, "close", figures.append)  # keep the figures to inspect
    assert main(["report", str(tmp_path), "--bootstrap", "100", "--out", str(tmp_path / "r")]) == 0
    curves = figures[0].axes[0]  # plot_curves draws first
    lines = {line.get_label(): line for line in curves.get_lines()}
    reference = lines["true-reward (n=2)"]
    assert reference.get_linestyle() == "--" and reference.get_color() == "black"
    assert list(reference.get_ydata()) == [450.0, 650.0]  # the mean over seeds at each step
    assert lines["root (n=2)"].get_linestyle() == "-"


def test_runs_of_one_method_with_other_settings_are_reported_apart(tmp_path, capsys):
    for seed, (feedback, value) in enumerate([(100, 300.0), (100, 320.0), (200, 500.0)]):
        path = tmp_path / f"root_{seed}"
        fake_run(path, "walker_walk", "root", seed, [100.0, value], max_feedback=feedback)
    # settings that do not change what a run learns (device, seed) never split a cell
    fake_run(tmp_path / "pairwise_0", "walker_walk", "pairwise", 0, [1.0, 2.0], device="cpu")
    fake_run(tmp_path / "pairwise_1", "walker_walk", "pairwise", 1, [1.0, 4.0], device="cuda")
    assert main(["report", str(tmp_path), "--bootstrap", "300", "--out", str(tmp_path / "r")]) == 0
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    assert report["methods"] == ["pairwise", "root/max_feedback=100", "root/max_feedback=200"]
    cells = {c["method"]: c for c in report["table"]}
    assert cells["root/max_feedback=100"]["mean"] == pytest.approx(310.0)
    assert cells["root/max_feedback=200"]["n"] == 1 and cells["pairwise"]["n"] == 2
    note = (
        "walker_walk: root runs differ in max_feedback; reported apart as "
        "root/max_feedback=100, root/max_feedback=200"
    )
    assert report["notes"] == [note]
    assert f"Note: {note}." in (tmp_path / "r" / "report.md").read_text()
    assert f"note: {note}" in capsys.readouterr().err


def test_a_learners_own_settings_split_only_that_learners_runs(tmp_path):
    """A RIME setting that plain runs hold with other values (or, made before it existed,
    not at all) does not split them; RIME runs that differ in it are reported apart."""
    fake_run(tmp_path / "plain_0", "walker_walk", "root", 0, [1.0, 2.0])
    fake_run(tmp_path / "plain_1", "walker_walk", "root", 1, [1.0, 4.0], rime_min_epochs=17)
    for seed, epochs in enumerate([17, 5]):
        settings = dict(reward_learner="rime", rime_min_epochs=epochs, surf_crop=seed)
        fake_run(tmp_path / f"rime_{seed}", "walker_walk", "root", seed, [1.0, 3.0], **settings)
    assert main(["report", str(tmp_path), "--bootstrap", "300", "--out", str(tmp_path / "r")]) == 0
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    assert report["methods"] == [
        "root",
        "root+rime/rime_min_epochs=17",
        "root+rime/rime_min_epochs=5",
    ]


def test_re_check_settings_split_only_checked_runs(tmp_path):
    """Runs of the paper's closure never read the re-check settings, whose default changed
    (twice from 20 pairs, then 5): old and new `full` runs stay one method; checked runs
    with different settings are reported apart."""
    fake_run(tmp_path / "full_0", "walker_walk", "root", 0, [1.0, 2.0], recheck_twice_gain=20)
    fake_run(tmp_path / "full_1", "walker_walk", "root", 1, [1.0, 4.0], recheck_twice_gain=5)
    for seed, twice in enumerate([20, 5]):
        settings = dict(augment="checked", recheck_twice_gain=twice)
        fake_run(tmp_path / f"checked_{seed}", "walker_walk", "root", seed, [1.0, 3.0], **settings)
    assert main(["report", str(tmp_path), "--bootstrap", "300", "--out", str(tmp_path / "r")]) == 0
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    assert report["methods"] == [
        "root",
        "root+checked/recheck_twice_gain=20",
        "root+checked/recheck_twice_gain=5",
    ]


def test_settings_are_compared_as_the_runs_read_them(tmp_path):
    """A run made before a setting existed reads today's default (its config.json lacks
    it), and one teacher never reads the crowd's settings, whose default changed (none to
    drop): such runs stay one method. Runs that differ in what they read stay apart, and a
    crowd's runs that differ in its weighting are reported apart."""
    fake_run(tmp_path / "old_0", "walker_walk", "root", 0, [1.0, 2.0], crowd_weighting="none")
    new = dict(reward_stop_on="all", crowd_weighting="drop", overlap_until=50)
    fake_run(tmp_path / "new_1", "walker_walk", "root", 1, [1.0, 4.0], **new)
    fake_run(tmp_path / "asked_2", "walker_walk", "root", 2, [1.0, 3.0], reward_stop_on="asked")
    crowd = "crowd:oracle+mistake"
    for seed, use in enumerate(["none", "drop"]):
        settings = dict(teacher=crowd, crowd_weighting=use)
        fake_run(
            tmp_path / f"crowd_{seed}", "walker_walk", "pairwise", seed, [1.0, 3.0], **settings
        )
    assert main(["report", str(tmp_path), "--bootstrap", "300", "--out", str(tmp_path / "r")]) == 0
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    cells = {c["method"]: c["n"] for c in report["table"]}
    assert cells == {
        "root/oracle/reward_stop_on=all": 2,
        "root/oracle/reward_stop_on=asked": 1,
        f"pairwise/{crowd}/crowd_weighting=drop": 1,
        f"pairwise/{crowd}/crowd_weighting=none": 1,
    }


def test_options_beyond_the_paper_name_their_own_methods(tmp_path):
    fake_run(tmp_path / "root_plain", "walker_walk", "root", 0, [1.0, 300.0])
    fake_run(tmp_path / "root_checked", "walker_walk", "root", 0, [1.0, 350.0], augment="checked")
    fake_run(
        tmp_path / "root_rime_qpa",
        "walker_walk",
        "root",
        0,
        [1.0, 400.0],
        reward_learner="rime",
        hybrid_replay=0.5,
    )
    warm = dict(reward_learner="rime", warm_start=1)
    fake_run(tmp_path / "root_rime_warm", "walker_walk", "root", 0, [1.0, 380.0], **warm)
    in_order = dict(segment_order="collection")
    fake_run(tmp_path / "root_collection", "walker_walk", "root", 0, [1.0, 390.0], **in_order)
    fake_run(tmp_path / "root_uniform", "walker_walk", "root", 1, [1.0, 310.0], **in_order)
    (tmp_path / "root_uniform" / "config.json").write_text(
        (tmp_path / "root_uniform" / "config.json").read_text().replace("collection", "uniform")
    )  # (named as the runs written before the setting, which lack it)
    assert main(["report", str(tmp_path), "--bootstrap", "300", "--out", str(tmp_path / "r")]) == 0
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    methods = ["root", "root+checked", "root+collection", "root+rime+qpa", "root+rime+warm"]
    assert sorted(report["methods"]) == methods
    assert report["notes"] == []  # nothing else differs: no split


def report_of(tmp_path, *options):
    argv = ["report", str(tmp_path / "runs"), "--bootstrap", "200", "--out", str(tmp_path / "r")]
    assert main([*argv, "--no-plots", *options]) == 0
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    cells = {(c["task"], c["method"]): c for c in report["table"]}
    return report, cells, (tmp_path / "r" / "report.md").read_text()


def test_a_task_without_a_success_signal_is_scored_by_its_return(tmp_path):
    runs = tmp_path / "runs"
    for seed, (hopper, walker) in enumerate([(86.0, 300.0), (120.0, 500.0)]):
        fake_run(runs / f"hopper_{seed}", "gym:Hopper-v5", "root", seed, [10.0, hopper])
        fake_run(runs / f"walker_{seed}", "walker_walk", "root", seed, [10.0, walker])
    report, cells, text = report_of(tmp_path)
    hopper = cells[("gym:Hopper-v5", "root")]
    assert hopper["metric"] == "return" and hopper["mean"] == pytest.approx(103.0)
    assert "gym:Hopper-v5,root,return,2," in (tmp_path / "r" / "report.csv").read_text()
    # Hopper's returns have no known range: the aggregate is walker's returns / 1000 alone
    assert report["aggregate_left_out"] == ["gym:Hopper-v5"]
    [aggregate] = report["aggregate_iqm"]
    assert aggregate["iqm"] == pytest.approx((0.3 + 0.5) / 2)
    assert "Scored by return on gym:Hopper-v5, walker_walk." in text
    assert "leaves out gym:Hopper-v5" in text


def test_a_custom_task_is_scored_by_success_once_its_runs_record_one(tmp_path):
    """The user's module is not importable where the report is made: it is never needed."""
    runs = tmp_path / "runs"
    for seed, success in enumerate([[0.0, 40.0], [20.0, 0.0]]):
        fake_run(runs / f"reach_{seed}", "absent_pkg.envs:reach", "root", seed, [5.0, 9.0], success)
        fake_run(runs / f"walk_{seed}", "absent_pkg.envs:walk", "root", seed, [5.0, 7.0 + seed])
    report, cells, text = report_of(tmp_path)
    reach, walk = cells[("absent_pkg.envs:reach", "root")], cells[("absent_pkg.envs:walk", "root")]
    assert reach["metric"] == "success" and reach["mean"] == pytest.approx(20.0)
    assert walk["metric"] == "return" and walk["mean"] == pytest.approx(7.5)
    [aggregate] = report["aggregate_iqm"]  # success / 100 of both reach runs: 0.4 and 0.0
    assert aggregate["iqm"] == pytest.approx(0.2)
    assert report["aggregate_left_out"] == ["absent_pkg.envs:walk"]
    assert "return on absent_pkg.envs:walk; success rate (%) on absent_pkg.envs:reach." in text


def test_unfinished_runs_are_left_out_unless_asked_for_and_then_marked(tmp_path):
    runs = tmp_path / "runs"
    for seed, value in enumerate([300.0, 340.0]):
        fake_run(runs / "walker" / f"root_{seed}", "walker_walk", "root", seed, [100.0, value])
    fake_run(runs / "walker" / "root_2", "walker_walk", "root", 2, [100.0], finished=False)
    report, cells, text = report_of(tmp_path)
    root = cells[("walker_walk", "root")]
    assert root["n"] == 2 and root["mean"] == pytest.approx(320.0) and root["partial"] == 0
    assert report["left_out"] == [
        {"run": "walker/root_2", "task": "walker_walk", "steps": 1000, "of": 2000}
    ]
    assert "Left out: 1 unfinished run" in text and "walker/root_2 (step 1,000 of 2,000)" in text

    report, cells, text = report_of(tmp_path, "--include-unfinished")
    root = cells[("walker_walk", "root")]
    assert root["n"] == 3 and root["mean"] == pytest.approx((300.0 + 340.0 + 100.0) / 3)
    assert report["left_out"] == [] and "Left out" not in text
    assert "(n=3, 1 unfinished at step 1,000) |" in text
    assert "| walker_walk | root (1 unfinished) |" in text  # the IQM table marks the method


def test_a_folder_of_unfinished_runs_only_is_a_clear_error(tmp_path, capsys):
    fake_run(tmp_path / "root_0", "walker_walk", "root", 0, [100.0], finished=False)
    assert main(["report", str(tmp_path), "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "none of its 1 runs has finished" in err and "--include-unfinished" in err


def sweep_of_variants(runs, variants, true_finals, root_finals):
    """Runs as a sweep plans them: every method, baselines included, once per variant."""
    for variant, settings in variants.items():
        for seed, (true, root) in enumerate(zip(true_finals, root_finals, strict=True)):
            for method, reward, final in (("root", "learned", root), ("true", "true", true)):
                name = f"{method}_{variant}_seed{seed}"
                args = ("walker_walk", "root", seed, [100.0, final])
                fake_run(runs / name, *args, reward=reward, **settings)
            floor = ("walker_walk", "root", seed, [50.0, 60.0 + seed])
            fake_run(runs / f"none_{variant}_seed{seed}", *floor, reward="none", **settings)


def test_baselines_are_one_method_whatever_feedback_settings_the_variants_change(tmp_path):
    variants = {
        "a": dict(max_feedback=100, reward_ensemble=3, unsup_steps=900, segment_length=50),
        "b": dict(max_feedback=200, reward_ensemble=5, unsup_steps=1800, segment_length=25),
    }
    sweep_of_variants(tmp_path / "runs", variants, [600.0, 640.0], [300.0, 330.0])
    report, cells, text = report_of(tmp_path)
    # the true-reward agent reads none of these: one column, one reference, each seed once
    assert report["reference"] == "true-reward"
    true = cells[("walker_walk", "true-reward")]
    assert true["n"] == 2 and true["std"] == pytest.approx(np.std([600.0, 640.0], ddof=1))
    learned = "root/max_feedback=100,reward_ensemble=3,segment_length=50,unsup_steps=900"
    assert cells[("walker_walk", learned)]["relative"] == pytest.approx(315.0 / 620.0)
    # a no-feedback run pre-trains, then follows its untrained ensemble: those settings count
    assert [m for m in report["methods"] if m.startswith("no-feedback")] == [
        "no-feedback/reward_ensemble=3,unsup_steps=900",
        "no-feedback/reward_ensemble=5,unsup_steps=1800",
    ]
    header = next(line for line in text.splitlines() if line.startswith("| task |"))
    assert header.count("true-reward") == 1
    assert any(n.startswith("walker_walk: true-reward runs of a seed") for n in report["notes"])


def test_a_baseline_run_once_per_variant_counts_each_seed_once(tmp_path):
    variants = {"q100": dict(max_feedback=100), "q200": dict(max_feedback=200)}
    sweep_of_variants(tmp_path / "runs", variants, [600.0, 640.0], [300.0, 330.0])
    report, cells, text = report_of(tmp_path)
    for method, finals in (("true-reward", [600.0, 640.0]), ("no-feedback", [60.0, 61.0])):
        cell = cells[("walker_walk", method)]
        assert cell["n"] == 2 and cell["mean"] == pytest.approx(np.mean(finals))
        assert cell["std"] == pytest.approx(np.std(finals, ddof=1))
    note = (
        "walker_walk: true-reward runs of a seed alike in every setting it reads count once; "
        "left out true_q200_seed0, true_q200_seed1"
    )
    assert note in report["notes"] and f"Note: {note}." in text


def test_a_sweeps_baselines_left_under_an_earlier_versions_names_count_once(tmp_path):
    """An earlier version planned each baseline once per variant; the sweep now plans one
    per seed (`sweep.json`), took one directory over and ran the no-feedback baseline again
    (its pre-training differed): the directories left count neither a second time nor as
    another method."""
    runs = tmp_path / "runs" / "walker_walk"
    for seed, final in enumerate([300.0, 330.0]):
        fake_run(runs / f"root_seed{seed}", "walker_walk", "root", seed, [100.0, final])
        true = ("walker_walk", "root", seed, [100.0, 600.0])
        fake_run(runs / f"true-reward_seed{seed}", *true, reward="true")
        floor = ("walker_walk", "root", seed, [50.0, 60.0])
        fake_run(runs / f"no-feedback_seed{seed}", *floor, reward="none", unsup_steps=900)
    fake_run(
        runs / "true-reward_q20_seed0", "walker_walk", "root", 0, [100.0, 900.0], reward="true"
    )
    old = ("walker_walk", "root", 0, [50.0, 10.0])
    fake_run(runs / "no-feedback_q10_seed0", *old, reward="none", unsup_steps=600)
    fake_run(runs / "no-feedback_q20_seed0", *old, reward="none", unsup_steps=600)
    names = [f"walker_walk/{d.name}" for d in runs.iterdir() if "_q" not in d.name]
    state = {"name": "grid", "runs": [{"name": name, "state": "finished"} for name in names]}
    (tmp_path / "sweep.json").write_text(json.dumps(state))

    report, cells, text = report_of(tmp_path)
    assert [m for m in report["methods"] if m != "root"] == ["no-feedback", "true-reward"]
    assert cells[("walker_walk", "true-reward")]["mean"] == 600.0
    assert cells[("walker_walk", "no-feedback")]["n"] == 2
    note = (
        "left out walker_walk/no-feedback_q10_seed0, walker_walk/no-feedback_q20_seed0, "
        "walker_walk/true-reward_q20_seed0: baseline runs an earlier version of the sweep made "
        "under another name, which it now plans and runs under its own"
    )
    assert report["notes"] == [note] and f"Note: {note}." in text
