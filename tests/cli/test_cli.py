from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import pytest

from seqrank.cli import main


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "seqrank", *args], capture_output=True, text=True, timeout=300
    )


def test_theory_json_has_the_documented_keys_and_exact_values(capsys):
    assert (
        main(
            [
                "theory",
                "--m",
                "4",
                "11",
                "--sessions",
                "200",
                "--enumerate-max",
                "5",
                "--format",
                "json",
            ]
        )
        == 0
    )
    payload = json.loads(capsys.readouterr().out)
    assert set(payload) == {"parameters", "rows", "disagreements", "paper_figure13"}
    by_m = {row["m"]: row for row in payload["rows"]}
    assert by_m[4]["sequential_enumerated"] == pytest.approx(3.75)
    assert by_m[4]["root_enumerated"] == pytest.approx(23 / 6)
    assert by_m[11]["sequential_enumerated"] is None
    assert by_m[11]["questions"] == 10
    assert any("Lemma 1" in line for line in payload["disagreements"])


def test_theory_table_shows_the_findings():
    result = run_cli("theory", "--m", "3", "5", "--sessions", "100", "--enumerate-max", "5")
    assert result.returncode == 0, result.stderr
    assert "Sequential: expected labelled pairs" in result.stdout
    assert "paper recurrence a_M (Lemma 1) disagrees for M = 5" in result.stdout


def test_simulate_writes_json_and_png(tmp_path, capsys):
    out = tmp_path / "sim"
    code = main(
        [
            "simulate",
            "--questions",
            "8",
            "--sessions",
            "5",
            "--schemes",
            "sequential,root",
            "--teachers",
            "oracle,equal",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    payload = json.loads((out / "simulate.json").read_text())
    assert [(r["scheme"], r["teacher"]) for r in payload["results"]] == [
        ("sequential", "oracle"),
        ("sequential", "equal"),
        ("root", "oracle"),
        ("root", "equal"),
    ]
    assert (out / "simulate.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Feedback efficiency" in capsys.readouterr().out


def test_simulate_json_on_stdout(tmp_path, capsys):
    code = main(
        [
            "simulate",
            "--questions",
            "4",
            "--sessions",
            "3",
            "--schemes",
            "pairwise",
            "--teachers",
            "mistake",
            "--out",
            str(tmp_path),
            "--no-plot",
            "--format",
            "json",
        ]
    )
    assert code == 0
    assert json.loads(capsys.readouterr().out)["results"][0]["pairs_per_question"] == 1.0
    assert not (tmp_path / "simulate.png").exists()


def test_simulate_takes_the_re_check_settings_of_checked(tmp_path, capsys):
    def ranked_oracle(*extra: str) -> dict[str, object]:
        args = ["simulate", "--questions", "20", "--sessions", "20", "--schemes", "ranked"]
        args += ["--teachers", "oracle", "--augment", "checked", "--out", str(tmp_path)]
        assert main([*args, "--no-plot", "--format", "json", *extra]) == 0
        return json.loads(capsys.readouterr().out)

    default, loose = ranked_oracle(), ranked_oracle("--recheck-gain", "3", "--path-unchecked", "2")
    assert default["parameters"]["recheck"] == {"gain": 1, "twice_gain": 5, "path_unchecked": 1}
    assert loose["parameters"]["recheck"]["gain"] == 3
    # fewer repeats and longer trusted paths infer more per question from the same answers
    ppq = [r["results"][0]["pairs_per_question"] for r in (default, loose)]
    assert ppq[1] > ppq[0] + 0.2


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["theory", "--m", "1"], "argument --m: 1 is out of range; accepted: 2 to 10000"),
        (["theory", "--m", "ten"], "'ten' is not a whole number"),
        (["theory", "--enumerate-max", "12"], "--enumerate-max 12 is too large"),
        (["theory", "--delta", "1.5"], "1.5 must lie strictly between 0 and 1"),
        (["theory", "--format", "xml"], "invalid choice: 'xml'"),
        (["simulate", "--questions", "0"], "0 is out of range; accepted: 1 to 10000"),
        (
            ["simulate", "--schemes", "sequential,tree"],
            "unknown scheme 'tree'; accepted: pairwise, sequential, root, ranked",
        ),
        (["simulate", "--teachers", "perfect"], "unknown teacher 'perfect'; accepted: oracle"),
        (["simulate", "--sessions", "1"], "1 is out of range; accepted: 2 to 1000000"),
        (["simulate", "--recheck-gain", "0"], "recheck settings gain 0, twice_gain 5"),
        (["fly"], "invalid choice: 'fly'"),
    ],
)
def test_bad_arguments_give_one_clear_line_and_exit_2(args, message):
    result = run_cli(*args)
    assert result.returncode == 2
    assert message in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert "Traceback" not in result.stderr


def test_every_train_setting_says_what_it_means_in_help():
    from dataclasses import fields

    from seqrank.cli.option_help import MEANINGS
    from seqrank.config import TrainConfig

    settings = {f.name for f in fields(TrainConfig)} - {"scale"}  # --scale has its own help
    assert settings == set(MEANINGS)
    shown = run_cli("train", "--help")
    assert "QPA: cut new segments from the last N episodes only" in " ".join(shown.stdout.split())


PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"
ENTRY = tomllib.loads(PYPROJECT.read_text())["project"]["scripts"]["seqrank"]  # module:function


def launch(how: str) -> list[str]:
    """The `seqrank` console script as installed (its wrapper calls the entry point named
    in pyproject.toml), or `python -m seqrank`."""
    if how == "python -m seqrank":
        return [sys.executable, "-m", "seqrank"]
    module, function = ENTRY.split(":")
    wrapper = f"from {module} import {function}; raise SystemExit({function}())"
    return [sys.executable, "-c", wrapper]


def torch_mapped(pid: int) -> bool:
    try:
        return "/torch/" in Path(f"/proc/{pid}/maps").read_text()
    except OSError:  # not started yet, or ended
        return False


@pytest.mark.parametrize("how", ["console script", "python -m seqrank"])
def test_ctrl_c_while_the_command_line_loads_is_one_line_and_130(how):
    """Ctrl-C in the first second or two of any command, while torch and the rest are
    imported, ends in one line and SIGINT's 130 (it printed a long traceback). The signal
    goes as soon as torch's libraries are in the process, so inside those imports on a
    loaded machine too (sooner, it could find Python itself starting, before any of
    seqrank's code); a command that ended before it is no failure, a traceback is."""
    if not Path("/proc/self/maps").exists():
        pytest.skip("needs /proc to see when torch loads")
    process = subprocess.Popen(
        [*launch(how), "theory", "--help"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    while process.poll() is None and time.monotonic() < deadline:
        if torch_mapped(process.pid):
            break
        time.sleep(0.005)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert "Traceback" not in err, err
    if process.returncode == 0:
        assert err == ""  # it ended before the signal: nothing to check
    else:
        assert (process.returncode, err) == (130, "interrupted\n")


def test_the_entry_point_imports_nothing_heavy():
    """What the console script imports before its `try` (the entry point's module): not
    the command line, torch or rich, so that the try holds every slow import."""
    module = ENTRY.split(":")[0]
    shown = "print(sorted({'seqrank.cli', 'torch', 'numpy', 'rich'} & set(sys.modules)))"
    code = f"import sys, {module}; {shown}"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.stdout.strip() == "[]", result.stderr
