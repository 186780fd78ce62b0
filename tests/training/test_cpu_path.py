"""What `--path auto` picks on a CPU (`seqrank.training.cpu_path`): the fast path in bf16
only with native bf16, at the sizes whose learning was checked, and when measured faster
on this machine; else the flat update in fp32 when measured faster; the measurement is
made once and kept."""

from __future__ import annotations

import json

import pytest
import torch

from seqrank.training import cpu_path
from seqrank.training.cpu_path import UpdateShape
from seqrank.training.runtime import resolve_runtime

CHECKED = UpdateShape(24, 6, 256, 2, 256)  # the small preset on walker_walk
SMALL = UpdateShape(24, 6, 64, 2, 64)
CPU = torch.device("cpu")


@pytest.fixture
def machine(monkeypatch, tmp_path):
    """A CPU whose flags and measured speed-up the test sets; a cache of its own."""
    monkeypatch.setenv("SEQRANK_CACHE", str(tmp_path))
    state = {
        "flags": {"avx512f", "avx512_bf16"},
        "capability": "AVX512",
        "speedup": {"bf16": 2.0, "fp32": 1.2},
        "measured": 0,
    }

    def measure(shape, precision):
        state["measured"] += 1
        return state["speedup"][precision]

    monkeypatch.setattr(cpu_path, "cpu_flags", lambda: state["flags"])
    monkeypatch.setattr(cpu_path, "torch_capability", lambda: state["capability"])
    monkeypatch.setattr(cpu_path, "_measure", measure)
    return state


def runtime(shape, path="auto", precision="auto"):
    return resolve_runtime(CPU, path, precision, discrete=False, shape=shape)


def test_native_bf16_measured_faster_at_checked_sizes_takes_the_fast_path(machine):
    chosen = runtime(CHECKED)
    assert chosen.fast and chosen.precision == "bf16" and chosen.path == "fast"


@pytest.mark.parametrize(
    ("flags", "capability", "bf16", "fp32", "expected"),
    [
        ({"avx2", "fma"}, "AVX2", 2.0, 1.14, "fp32"),  # no native bf16: the flat update in fp32
        ({"avx512_bf16"}, "AVX2", 2.0, 1.14, "fp32"),  # torch's kernels held at AVX2
        ({"avx512_bf16"}, "AVX512", 1.1, 1.14, "fp32"),  # native, bf16 not faster enough
        ({"avx2", "fma"}, "AVX2", 2.0, 1.01, None),  # neither measured faster: reference
    ],
)
def test_without_a_fast_bf16_auto_takes_the_flat_update_in_fp32_where_measured_faster(
    machine, flags, capability, bf16, fp32, expected
):
    machine.update(flags=flags, capability=capability, speedup={"bf16": bf16, "fp32": fp32})
    chosen = runtime(CHECKED)
    if expected is None:
        assert not chosen.fast and chosen.precision == "fp32"
    else:
        assert chosen.fast and chosen.precision == expected


def test_smaller_networks_than_those_checked_stay_on_the_reference_path(machine):
    machine["flags"] = {"amx_bf16"}
    chosen = runtime(SMALL)
    assert not chosen.fast and chosen.precision == "fp32" and machine["measured"] == 0


def test_what_the_user_chose_is_never_overruled(machine):
    assert not runtime(CHECKED, path="reference").fast
    assert runtime(CHECKED, precision="fp32") == resolve_runtime(CPU, "auto", "fp32", False)
    assert runtime(CHECKED, path="fast", precision="fp32").precision == "fp32"
    assert not resolve_runtime(CPU, "auto", "auto", discrete=True, shape=CHECKED).fast
    assert not runtime(None).fast  # no shape, nothing measured


def test_the_measurement_is_made_once_per_machine_and_shape(machine, tmp_path):
    runtime(CHECKED)
    runtime(CHECKED)
    assert machine["measured"] == 1
    ((key, value),) = json.loads((tmp_path / "cpu-paths.json").read_text()).items()
    assert value == 2.0 and "'hidden': 256" in key and "threads" in key and key.endswith("bf16")
    runtime(UpdateShape(24, 6, 256, 3, 256))
    assert machine["measured"] == 2


def test_a_real_measurement_leaves_the_global_random_state_alone():
    before = torch.random.get_rng_state()
    for precision in ("fp32", "bf16"):
        assert cpu_path._measure(UpdateShape(3, 1, 8, 1, 8), precision) > 0
    assert torch.equal(torch.random.get_rng_state(), before)


@pytest.mark.parametrize(
    ("cores", "torch_threads", "fast", "expected"),
    [
        (2, 2, True, 1),  # one core left to the evaluation process and the simulator
        (8, 8, True, 7),
        (8, 3, True, 3),  # never more than torch's own setting (OMP_NUM_THREADS, a sweep's)
        (1, 1, True, 1),
        (2, 2, False, 2),  # the reference path evaluates inline: torch's setting
    ],
)
def test_a_cpu_run_leaves_a_core_to_its_evaluation_on_the_fast_path(
    monkeypatch, cores, torch_threads, fast, expected
):
    monkeypatch.setattr(cpu_path.os, "sched_getaffinity", lambda _: set(range(cores)))
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(torch_threads)
        assert cpu_path.training_threads(fast) == expected
        with cpu_path.torch_threads(expected):
            assert torch.get_num_threads() == expected
        assert torch.get_num_threads() == torch_threads  # put back
    finally:
        torch.set_num_threads(before)


def test_the_measurement_runs_with_the_threads_a_fast_run_trains_with(machine, monkeypatch):
    monkeypatch.setattr(cpu_path.os, "sched_getaffinity", lambda _: {0, 1})
    seen: list[int] = []

    def measure(shape, precision):
        seen.append(torch.get_num_threads())
        return 2.0

    monkeypatch.setattr(cpu_path, "_measure", measure)
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        assert cpu_path.measured_speedup(CHECKED) == 2.0
        assert seen == [1] and torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
