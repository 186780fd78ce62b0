"""`seqrank bench`: both paths timed in one run, written as JSON and Markdown."""

from __future__ import annotations

import json

import pytest

from seqrank.bench.report import format_markdown
from seqrank.bench.suite import ratios, summarise
from seqrank.cli import main
from seqrank.config import resolve_config

TINY = ["--set", "hidden=32", "--set", "batch=32", "--set", "reward_hidden=32"]


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "bench-cpu"
    args = ["bench", "--task", "dmc:cartpole_swingup", "--device", "cpu", "--repeats", "2"]
    args += ["--updates", "5", "--reward-epochs", "1", "--loop-steps", "300", *TINY]
    assert main([*args, "--precisions", "fp32", "--out", str(out)]) == 0
    return out


def test_bench_writes_every_number_for_both_paths(bench):
    result = json.loads(bench.with_suffix(".json").read_text())
    assert result["settings"]["hidden"] == 32 and result["settings"]["repeats"] == 2
    assert set(result["variants"]) == {"reference", "fast-fp32"}
    for row in result["variants"].values():
        assert len(row["update_us_rounds"]) == len(row["loop_steps_per_s_rounds"]) == 2
        for key in ("update_us", "reward_epoch_us", "loop_steps_per_s", "session_s"):
            assert row[key] > 0, key
        # the loop's cost beside the update: part of a step, never all of it
        assert 0 < row["collect_us"] < 1e6 / row["loop_steps_per_s"]
        assert row["update_us"] == pytest.approx(sum(row["update_us_rounds"]) / 2, abs=0.1)
        assert row["capture_s"] == 0.0  # no CUDA graph on a CPU
    ref, fast = result["variants"]["reference"], result["variants"]["fast-fp32"]
    assert result["ratios"]["fast-fp32"]["update"] == pytest.approx(
        ref["update_us"] / fast["update_us"]
    )
    assert result["ratios"]["fast-fp32"]["loop"] == pytest.approx(
        fast["loop_steps_per_s"] / ref["loop_steps_per_s"]
    )
    markdown = bench.with_suffix(".md").read_text()
    assert "| SAC update (µs) |" in markdown and "fast-fp32 / reference" in markdown
    assert "| collection step: action, simulator, store (µs) |" in markdown
    assert "Command: `seqrank bench --task dmc:cartpole_swingup --device cpu" in markdown
    assert "CUDA graph" not in markdown  # captured on CUDA only: no row of zeros on a CPU


@pytest.mark.parametrize(("native", "expected"), [(True, ["fp32", "bf16"]), (False, ["fp32"])])
def test_the_cpu_benchmark_times_bf16_where_the_processor_has_it(monkeypatch, native, expected):
    from seqrank.cli import bench as bench_cli
    from seqrank.training import cpu_path

    monkeypatch.setattr(cpu_path, "native_bf16", lambda: native)
    assert bench_cli._precisions(None, "cpu") == expected
    assert bench_cli._precisions(None, "cuda") == ["tf32", "bf16", "fp32"]


def test_projection_adds_steps_sessions_and_evaluations():
    config = resolve_config("walker_walk", "paper", {})  # 500K steps, 10 sessions
    rounds = [{"us": 100.0, "capture_s": 1.0}, {"us": 300.0, "capture_s": 2.0}]
    loops = [{"steps_per_s": 1000.0, "collect_us": 9.0, "session_s": 2.0, "eval_episode_s": 0.5}]
    loops *= 3
    row = summarise({"update": rounds, "reward": [5.0, 7.0], "loop": loops}, config)
    assert row["update_us"] == 200.0 and row["capture_s"] == 2.0 and row["reward_epoch_us"] == 6
    evaluations = 500_000 // 10_000
    assert row["projected_full_run_s"] == pytest.approx(500 + 10 * 2.0 + evaluations * 10 * 0.5)
    faster = dict(row, update_us=50.0, loop_steps_per_s=4000.0)
    table = ratios({"reference": row, "fast-tf32": faster})["fast-tf32"]
    assert table["update"] == 4.0 and table["loop"] == 4.0
    result = {
        "device": "test",
        "torch": "x",
        "settings": {
            "task": "walker_walk",
            "scale": "paper",
            "hidden": 1024,
            "layers": 2,
            "batch": 1024,
            "reward_ensemble": 3,
            "reward_hidden": 256,
            "steps": 500_000,
            "sessions": 10,
            "eval_every": 10_000,
            "eval_episodes": 10,
            "repeats": 3,
            "updates": 200,
            "reward_epochs": 5,
            "loop_steps": 2000,
        },
        "variants": {"reference": row, "fast-tf32": faster},
        "ratios": {"fast-tf32": table},
    }
    assert "| SAC update (µs) | 200 | 50 | 4.00x |" in format_markdown(result)
    cuda = format_markdown({**result, "device": "cuda"})
    assert "| CUDA graph capture (s) | 2.00 |" in cuda


@pytest.mark.parametrize("there", [".json", ".md"])
def test_a_bench_refuses_a_result_already_there(there, tmp_path, monkeypatch, capsys):
    """OUT.json and OUT.md are new files: one already there is refused in one line before
    anything is timed (it was overwritten silently), and nothing is written."""
    from seqrank.bench import suite

    def timed(*args, **kwargs):
        raise AssertionError("timed")

    monkeypatch.setattr(suite, "run_bench", timed)
    out = tmp_path / "bench-cpu"
    out.with_suffix(there).write_text("mine\n")
    args = ["bench", "--task", "dmc:cartpole_swingup", "--device", "cpu", *TINY]
    assert main([*args, "--out", str(out)]) == 2
    said = capsys.readouterr().err
    written = out.with_suffix(there)
    assert said.endswith(
        f"bench result {written} already exists; choose another --out or remove it\n"
    )
    assert said.count("\n") == 1
    assert [p.name for p in tmp_path.iterdir()] == [written.name]
    assert written.read_text() == "mine\n"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--precisions", "fp16"], "unknown precision 'fp16'; accepted: fp32, tf32, bf16"),
        (["--loop-steps", "50"], "--loop-steps: 50 is out of range; accepted: 300 to"),
        (["--task", "block:place"], "learns with DQN"),
        (["--set", "hidden"], "expected FIELD=VALUE"),
        (["--set", "hidden=big"], "'big' is not a int"),
        (["--repeats", "0"], "--repeats: 0 is out of range; accepted: 1 to 1000"),
    ],
)
def test_bad_bench_options_are_named(args, message, capsys, tmp_path):
    assert main(["bench", "--device", "cpu", "--out", str(tmp_path / "b"), *args]) == 2
    assert message in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
