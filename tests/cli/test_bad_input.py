"""Bad input to every command: exit code 2, one line on stderr that names the bad value and
what is accepted, no traceback, and nothing made on disk (in the working folder, at the
output path, or in the folders the command was given)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from seqrank.cli import main
from seqrank.episodes import Episode
from seqrank.rewardbench.pool import pool_from_episodes, save_pool
from seqrank.training.runs import RunDir
from support.datasets import write_datasets
from support.labels import write_labels
from support.runs import tiny_config

TOML = """
device = "cpu"
tasks = ["dmc:cartpole_swingup"]
schemes = ["root"]
out = "{out}"
{extra}
"""


@pytest.fixture
def given(tmp_path: Path) -> dict[str, str]:
    """Things a command may be pointed at: a plain file, a folder, a run directory (no
    checkpoint), a folder of runs, sweep files, label files (sequential answers on
    dmc:cartpole_swingup, two sessions of 4 on 20-step segments; one of 7 features per step
    that names no task; one of two schemes), a reward-bench pool (a run's 4 episodes of 100
    steps)."""
    folder = tmp_path / "given"
    (folder / "runs").mkdir(parents=True)
    (folder / "a-file").write_text("not a folder\n")
    run = RunDir.create(folder / "runs" / "run", tiny_config(), "cpu")
    run.release()
    labels = {
        "labels": write_labels(folder / "labels.jsonl"),
        "labels_wide": write_labels(folder / "wide.jsonl", task=None, features=7),
        "labels_mixed": write_labels(folder / "mixed.jsonl", schemes=("sequential", "root")),
    }
    sweeps = {
        "toml": TOML.format(out=folder / "sweep-out", extra=""),
        "toml_out_file": TOML.format(out=folder / "a-file", extra=""),
        "toml_discount": TOML.format(out=folder / "sweep-out", extra="[overrides]\ndiscount = 2"),
        "toml_replay": TOML.format(
            out=folder / "sweep-out", extra=f'teachers = ["replay:{labels["labels"]}"]'
        ),
    }
    for name, text in sweeps.items():
        (folder / f"{name}.toml").write_text(text)
    steps = np.zeros((100, 3), np.float32)
    episodes = [Episode(steps, steps[:, :1], np.zeros(100)) for _ in range(4)]
    save_pool(pool_from_episodes("cartpole_swingup", episodes, 0, [], {}), folder / "pool.npz")
    datasets = write_datasets(folder / "datasets")
    return {
        "file": str(folder / "a-file"),
        "dir": str(folder),
        "run": str(folder / "runs" / "run"),
        "runs": str(folder / "runs"),
        "pool": str(folder / "pool.npz"),
        **{name: str(path) for name, path in labels.items()},
        **datasets,
        **{name: str(folder / f"{name}.toml") for name in sweeps},
    }


TRAIN = ["train", "--device", "cpu", "--task", "dmc:cartpole_swingup"]
OFFLINE = ["label", "offline", "--task", "dmc:cartpole_swingup", "--port", "0"]
ONLINE = ["label", "online", "--device", "cpu", "--port", "0", "--out", "online-run"]
STUDY = ["label", "study", "--participant", "p1", "--device", "cpu", "--port", "0"]

MAKE = ["dataset", "make", "--task", "dmc:cartpole_swingup", "--out", "{dir}/new"]
DATASET_PAGE = ["label", "offline", "--port", "0", "--dataset"]
POOL = ["reward-bench", "pool", "--out", "{dir}/pool-new.npz", "--from-dataset"]
RANDOM_ONE = ["dataset", "make", "--source", "random", "--episodes", "1"]

CASES = [
    # train: ranges of the settings, and what they imply
    ([*TRAIN, "--discount", "1.5"], "--discount must be a number in (0, 1], got 1.5"),
    ([*TRAIN, "--discount", "0"], "--discount must be a number in (0, 1], got 0.0"),
    ([*TRAIN, "--tau", "2"], "--tau must be a number in (0, 1], got 2.0"),
    ([*TRAIN, "--reward-stop-accuracy", "1.5"], "--reward-stop-accuracy must be a number in (0, 1"),
    ([*TRAIN, "--actor-lr", "nan"], "--actor-lr must be a finite number > 0, got nan"),
    ([*TRAIN, "--critic-lr", "inf"], "--critic-lr must be a finite number > 0, got inf"),
    ([*TRAIN, "--reward-lr", "-0.1"], "--reward-lr must be a finite number > 0, got -0.1"),
    ([*TRAIN, "--init-temperature", "0"], "--init-temperature must be a finite number > 0"),
    ([*TRAIN, "--seed", "-1"], "--seed must be a whole number from 0 to 4294967295, got -1"),
    ([*TRAIN, "--seed", "99999999999999999999"], "--seed must be a whole number from 0 to 42949"),
    ([*TRAIN, "--steps", "0"], "--steps must be a whole number from 1 to 2147483647, got 0"),
    ([*TRAIN, "--hidden", "-3"], "--hidden must be a whole number from 1 to 2147483647, got -3"),
    ([*TRAIN, "--record-states", "2"], "--record-states must be a whole number from 0 to 1, got 2"),
    ([*TRAIN, "--hidden", "big"], "argument --hidden: invalid int value: 'big'"),
    ([*TRAIN, "--knn-k", "2000"], "--knn-k 2000 must be smaller than --seed-steps 1000"),
    ([*TRAIN, "--oversample", "1000"], "--oversample must be a whole number from 1 to 100, got"),
    ([*TRAIN, "--heldout-pairs", "10000000"], "--heldout-pairs must be a whole number from 1 to"),
    (  # 1.2 TiB of replay buffer: more than any machine's memory
        ["train", "--device", "cpu", "--task", "humanoid_walk", "--steps", "2147483647"],
        "error: --steps 2147483647: the replay buffer keeps every step, 1,264.0 GiB, more",
    ),
    ([*TRAIN, "--max-feedback", "100000"], "impossible budget"),
    # query-policy alignment (QPA)
    ([*TRAIN, "--hybrid-replay", "1.5"], "--hybrid-replay must be a number in [0, 1], got 1.5"),
    ([*TRAIN, "--hybrid-replay", "-0.5"], "--hybrid-replay must be a number in [0, 1], got -0.5"),
    ([*TRAIN, "--hybrid-replay", "nan"], "--hybrid-replay must be a number in [0, 1], got nan"),
    ([*TRAIN, "--hybrid-episodes", "0"], "--hybrid-episodes must be a whole number from 1 to"),
    ([*TRAIN, "--query-episodes", "-1"], "--query-episodes must be a whole number from 0 to"),
    (
        [*TRAIN, "--episodes-kept", "20", "--query-episodes", "30"],
        "--query-episodes 30 exceeds --episodes-kept 20: segments are cut from the",
    ),
    ([*TRAIN, "--reward", "true", "--hybrid-replay", "0.5"], "--reward 'true' asks none: leave"),
    ([*TRAIN, "--segment-order", "sideways"], "unknown --segment-order 'sideways'; accepted: uni"),
    (
        [*TRAIN, "--segment-order", "collection", "--reward", "none"],
        "--segment-order collection orders the segments of questions; --reward 'none' asks none",
    ),
    (
        [*TRAIN, "--segment-order", "collection", "--selection", "entropy"],
        "--segment-order collection gives the scheme its segments as they come; --selection ent",
    ),
    (
        [*TRAIN, "--segment-order", "collection", "--parts", "low,varied"],
        "ordered by skill level, not by when they were collected; --segment-order collection",
    ),
    (
        [*TRAIN, "--segment-order", "collection", "--teacher", "replay:{labels}"],
        "replays recorded segments; --segment-order collection orders new ones: leave it out",
    ),
    (
        [*TRAIN, "--reward", "true", "--reward-learner", "rime"],
        "--reward-learner acts on what answers teach the reward model; --reward 'true' asks",
    ),
    (
        [*TRAIN, "--reward", "none", "--augment", "checked", "--warm-start", "1"],
        "--augment and --warm-start act on what answers teach the reward model; --reward 'none'",
    ),
    (
        [*TRAIN, "--reward", "true", "--augment", "checked"],
        "--reward 'true' asks for none: leave it",
    ),
    ([*TRAIN, "--parts", "low", "--query-episodes", "4"], "--query-episodes would drop some"),
    # the reward learners (SURF, RIME) and the warm start
    ([*TRAIN, "--reward-learner", "best"], "unknown --reward-learner 'best'; accepted: plain"),
    ([*TRAIN, "--surf-threshold", "1.5"], "--surf-threshold must be a number in (0, 1], got 1.5"),
    ([*TRAIN, "--surf-unlabelled-ratio", "0"], "--surf-unlabelled-ratio must be a whole number"),
    (
        [*TRAIN, "--reward-learner", "surf", "--surf-crop", "50"],
        "--surf-crop 50 must be smaller than --segment-length 50",
    ),
    ([*TRAIN, "--rime-beta-min", "5"], "--rime-beta-min 5.0 exceeds --rime-beta-max 3.0"),
    ([*TRAIN, "--rime-tau-upper", "0.6"], "--rime-tau-upper must be below 0.5, got 0.6"),
    ([*TRAIN, "--rime-decay-updates", "0"], "--rime-decay-updates must be a whole number from 1"),
    (
        [*TRAIN, "--reward-learner", "rime", "--reward-epochs", "20", "--rime-min-epochs", "25"],
        "--rime-min-epochs 25 exceeds --reward-epochs 20, the most a fit runs; accepted: 1 to 20",
    ),
    ([*TRAIN, "--warm-start", "2"], "--warm-start must be a whole number from 0 to 1, got 2"),
    ([*TRAIN, "--segment-length", "5000"], "--segment-length 5000 is longer than an episode"),
    # --dry-run makes the checks that need the task's environment too
    ([*TRAIN, "--dry-run", "--segment-length", "5000"], "--segment-length 5000 is longer than"),
    ([*TRAIN, "--dry-run", "--seed-steps", "10", "--unsup-steps", "0"], "before the first"),
    (
        [*TRAIN, "--dry-run", "--steps", "2147483647", "--feedback-frequency", "100000000"],
        "--steps 2147483647: the replay buffer keeps every step",
    ),
    ([*TRAIN, "--teacher", "replay:missing.jsonl"], "label file missing.jsonl does not exist"),
    # replayed labels: a setting given otherwise than the file recorded it, and --dry-run
    # checks the file as the run does
    *[
        (
            [*TRAIN, *dry, "--teacher", "replay:{labels}", *setting],
            f"error: {setting[0]} {setting[1]} conflicts with the replay file's {what} "
            f"({{labels}}); leave {setting[0]} out to take the file's",
        )
        for dry in ([], ["--dry-run"])
        for setting, what in [
            (["--scheme", "root"], "scheme sequential"),
            (["--segment-length", "25"], "segment length 20"),
            (["--reward-batch", "10"], "questions per session 4"),
            (["--task", "dmc:walker_walk"], "task dmc:cartpole_swingup"),
        ]
    ],
    (
        [*TRAIN, "--teacher", "replay:{labels}", "--max-feedback", "100"],
        "--max-feedback 100 exceeds the 8 answers of the replay file ({labels}); accepted: 1 to 8",
    ),
    (
        [*TRAIN, "--teacher", "replay:{labels}", "--selection", "disagreement"],
        "--selection disagreement picks new segments to ask about; the replay file's were",
    ),
    ([*TRAIN, "--dry-run", "--teacher", "replay:missing.jsonl"], "missing.jsonl does not exist"),
    ([*TRAIN, "--dry-run", "--teacher", "replay:{file}"], "error: {file} line 1: not JSON"),
    (
        [*TRAIN, "--dry-run", "--teacher", "replay:{labels_wide}"],
        "label file {labels_wide} has 7 features per step; task dmc:cartpole_swingup needs 6",
    ),
    (
        [*TRAIN, "--dry-run", "--teacher", "replay:{labels_mixed}"],
        "label file {labels_mixed} holds several schemes (root, sequential); a run replays",
    ),
    # a simulated crowd: its settings, its members, and its settings without one
    (
        [*TRAIN, "--overlap", "1.5", "--teacher", "crowd:oracle+noisy", "--dry-run"],
        "--overlap must be a number in [0, 1], got 1.5",
    ),
    ([*TRAIN, "--overlap", "0.5"], "on a crowd's answers; --teacher 'oracle' is one teacher"),
    ([*TRAIN, "--teacher", "crowd:oracle++noisy"], "an empty crowd member"),
    ([*TRAIN, "--teacher", "crowd:oracle,time=0"], "time must be a number of seconds > 0"),
    (
        [*TRAIN, "--teacher", "crowd:oracle+noisy", "--crowd-weighting", "soft"],
        "unknown --crowd-weighting 'soft'; accepted: reliability, none, drop",
    ),
    (
        [*TRAIN, "--teacher", "crowd:oracle+noisy", "--overlap-until", "-1", "--dry-run"],
        "--overlap-until must be a whole number from 0 to 10000, got -1",
    ),
    ([*TRAIN, "--overlap-until", "40"], "--overlap-until acts on a crowd's answers; --teacher"),
    (
        [*TRAIN, "--teacher", "crowd:oracle+noisy", "--closure-checks", "2", "--dry-run"],
        "--closure-checks must be a whole number from 0 to 1, got 2",
    ),
    ([*TRAIN, "--teacher", "perfect"], "unknown --teacher 'perfect'; accepted: oracle"),
    ([*TRAIN, "--task", "walker"], "unknown --task 'walker'; accepted: walker_walk"),
    ([*TRAIN, "--precision", "tf32"], "--precision 'tf32' needs the fast path"),
    ([*TRAIN, "--precision", "fp16"], "unknown --precision 'fp16'; accepted: auto, fp32, tf32"),
    ([*TRAIN, "--path", "quick"], "unknown --path 'quick'; accepted: auto, reference, fast"),
    ([*TRAIN, "--scheme", "tree"], "unknown --scheme 'tree'; accepted: pairwise, sequential"),
    ([*TRAIN, "--backbone", "ppo"], "unknown --backbone 'ppo'; accepted: pebble, mrn"),
    ([*TRAIN, "--selection", "best"], "unknown --selection 'best'; accepted: uniform"),
    ([*TRAIN, "--augment", "strict"], "unknown --augment 'strict'; accepted: full, checked"),
    ([*TRAIN, "--recheck-gain", "0"], "--recheck-gain must be a whole number from 1"),
    ([*TRAIN, "--path-unchecked", "-1"], "--path-unchecked must be a whole number from 0"),
    (
        [*TRAIN, "--augment", "checked", "--recheck-gain", "9", "--recheck-twice-gain", "3"],
        "--recheck-twice-gain 3 is below --recheck-gain 9",
    ),
    ([*TRAIN, "--scale", "huge"], "argument --scale: invalid choice: 'huge'"),
    (["train", "--device", "tpu"], "unknown --device 'tpu'; accepted: auto, cpu, cuda"),
    ([*TRAIN, "--reward-batch", "500", "--max-feedback", "100"], "exceeds --max-feedback 100"),
    (["train", "--resume", "/nonexistent/run"], "no run directory at /nonexistent/run"),
    ([*TRAIN, "--wandb", " "], "--wandb needs a project name"),
    ([*TRAIN, "--out", "{file}"], "run directory {file} is a file, not a folder"),
    ([*TRAIN, "--out", "{file}/run"], "{file} is a file, not a folder"),
    ([*TRAIN, "--out", "{dir}"], "run directory {dir} is not empty; resume it with --resume"),
    (["train", "--resume", "{file}"], "no run directory at {file} (config.json missing)"),
    (["train", "--resume", "{run}", "--steps", "10"], "drop --steps"),
    # label: the page's options, the offline settings, online and study settings
    ([*OFFLINE, "--port", "70000"], "70000 is out of range; accepted: 0 to 65535"),
    ([*OFFLINE, "--countdown", "nan"], "--countdown nan: must be 0 (none) or more seconds"),
    ([*OFFLINE, "--allow-host", "bad host"], "'bad host' is not a host name or address: give"),
    ([*OFFLINE, "--allow-host", "labels.example.org:80"], "is not a host name or address"),
    ([*OFFLINE, "--size", "2000"], "2000 is out of range; accepted: 16 to 480"),
    ([*OFFLINE, "--fps", "0"], "argument --fps: 0 is out of range; accepted: 1 to 120"),
    ([*OFFLINE, "--seed", "-1"], "argument --seed: -1 is out of range; accepted: 0 to 4294967295"),
    ([*OFFLINE, "--questions", "0"], "argument --questions: 0 must be at least 1"),
    ([*OFFLINE, "--segment-length", "5000"], "--segment-length 5000 is longer than an episode"),
    ([*OFFLINE, "--out", "{file}"], "labelling directory {file} is a file, not a folder"),
    (["label", "offline", "--from", "{run}"], "{run} has no checkpoint yet"),
    (["label", "offline", "--task", "nope"], "unknown --task 'nope'"),
    ([*ONLINE, "--discount", "2"], "error: --discount must be a number in (0, 1], got 2.0"),
    ([*ONLINE, "--query-episodes", "500"], "--query-episodes 500 exceeds --episodes-kept 100"),
    ([*ONLINE, "--teacher", "oracle"], "the labelling page's teacher is the person"),
    # label: a team (issue 37)
    ([*ONLINE, "--annotators", "alice,alice"], "--annotators 'alice,alice': alice given twice"),
    ([*OFFLINE, "--annotators", "alice,bob,alice"], "alice given twice; names are unique"),
    ([*ONLINE, "--annotators", "alice,,bob"], "--annotators 'alice,,bob'"),
    ([*OFFLINE, "--annotators", "al ice"], "--annotators 'al ice'"),
    ([*ONLINE, "--annotators", "alice,bob", "--overlap", "1.5"], "--overlap must be a number in"),
    ([*OFFLINE, "--annotators", "alice,bob", "--overlap", "1.5"], "1.5 is out of range; accepted"),
    ([*ONLINE, "--overlap", "0.5"], "one teacher: leave them out, or name a team with --annotat"),
    ([*OFFLINE, "--overlap", "0.5"], "--overlap 0.5 acts on a team's answers; one person answers"),
    ([*ONLINE, "--crowd-weighting", "reliability"], "--crowd-weighting acts on a crowd's answe"),
    (
        [*ONLINE, "--annotators", "alice,bob", "--closure-checks", "1"],
        "--closure-checks 1: the labelling page asks others about the pair a member answered",
    ),
    ([*OFFLINE, "--overlap-until", "20"], "--overlap-until 20 acts on a team's answers; one per"),
    (
        [*OFFLINE, "--annotators", "alice,bob", "--overlap-until", "-3"],
        "--overlap-until: -3 is out of range; accepted",
    ),
    # label: gold pairs (issue 49)
    ([*OFFLINE, "--gold", "{labels}"], "--gold {labels} acts on a team's answers; one person"),
    ([*OFFLINE, "--annotators", "a,b", "--gold", "gold.jsonl"], "gold file gold.jsonl does not"),
    (
        [*OFFLINE, "--annotators", "a,b", "--gold", "{labels}"],
        "gold file {labels} holds segments of 20 steps; this run asks about 50",
    ),
    (
        [*ONLINE, "--annotators", "a,b", "--gold", "{labels_wide}"],
        "gold file {labels_wide} is of task None; this run's is",
    ),
    ([*ONLINE, "--port", "-1"], "argument --port: -1 is out of range; accepted: 0 to 65535"),
    ([*STUDY, "--seed", "-5"], "error: --seed must be a whole number from 0 to 4294967295"),
    ([*STUDY, "--methods", "root,foo"], "--methods 'root,foo': give distinct schemes"),
    ([*STUDY, "--task", "dmc:cheetah_run", "--max-feedback", "200"], "impossible budget"),
    # labels
    (
        ["labels", "export", "{file}", "-o", "x.jsonl"],
        "{file} holds no labels.sqlite (a labelling directory) nor config.json",
    ),
    (["labels", "export", "{run}", "-o", "{dir}"], "label file {dir} is a folder"),
    (["labels", "import", "missing.jsonl", "new"], "label file missing.jsonl does not exist"),
    (["labels", "import", "{file}", "new"], "{file} line 1: not JSON"),
    # sweep
    (["sweep", "missing.toml"], "sweep file missing.toml does not exist"),
    (["sweep", "{toml}", "--workers", "0"], "argument --workers: 0 is out of range"),
    (["sweep", "{toml}", "--cpus-per-run", "nan"], "argument --cpus-per-run: nan is out of range"),
    (["sweep", "{toml}", "--gpus-per-run", "-1"], "argument --gpus-per-run: -1.0 is out of range"),
    (["sweep", "{toml_out_file}"], "sweep folder {file} is a file, not a folder"),
    (["sweep", "{toml_discount}"], "seed 0: discount must be a number in (0, 1], got 2"),
    (
        ["sweep", "{toml_replay}", "--dry-run"],
        "scheme root conflicts with the replay file's scheme sequential ({labels}); leave "
        "scheme out",
    ),
    # report
    (["report", "{file}"], "{file} is not a folder"),
    (["report", "{runs}"], "{runs}: none of its 1 runs has finished (no summary.json)"),
    (
        ["report", "{runs}", "--include-unfinished", "--out", "{file}"],
        "report folder {file} is a file, not a folder",
    ),
    (["report", "{runs}", "--bootstrap", "10"], "argument --bootstrap: 10 is out of range"),
    (["report", "{runs}", "--seed", "-1"], "argument --seed: -1 is out of range"),
    # bench
    (["bench", "--repeats", "0"], "argument --repeats: 0 is out of range; accepted: 1 to 1000"),
    (["bench", "--loop-steps", "50"], "argument --loop-steps: 50 is out of range; accepted: 300"),
    (["bench", "--device", "cpu", "--set", "discount=2"], "discount must be a number in (0, 1]"),
    (["bench", "--device", "cpu", "--set", "nope=1"], "--set 'nope=1': expected FIELD=VALUE"),
    (["bench", "--device", "cpu", "--out", "{file}/x"], "{file} is a file, not a folder"),
    (["bench", "--device", "cpu", "--precisions", "fp16"], "unknown precision 'fp16'"),
    (["bench", "--device", "tpu"], "argument --device: invalid choice: 'tpu'"),
    # theory, simulate
    (["theory", "--m", "1"], "argument --m: 1 is out of range; accepted: 2 to 10000"),
    (["theory", "--m", "100000000"], "argument --m: 100000000 is out of range"),
    (["theory", "--seed", "-1"], "argument --seed: -1 is out of range"),
    (["theory", "--delta", "1.5"], "1.5 must lie strictly between 0 and 1"),
    (["theory", "--enumerate-max", "12"], "--enumerate-max 12 is too large"),
    (["simulate", "--questions", "100000000000"], "100000000000 is out of range; accepted: 1"),
    (["simulate", "--seed", "-1"], "argument --seed: -1 is out of range"),
    (["simulate", "--out", "{file}"], "--out {file} is a file, not a folder"),
    (["simulate", "--schemes", "tree"], "unknown scheme 'tree'; accepted: pairwise"),
    (["simulate", "--teachers", "crowd:oracle++noisy"], "an empty crowd member; write members"),
    (["simulate", "--teachers", "crowd:oracle,name=a+noisy,name=a"], "member name 'a' must be"),
    (["simulate", "--overlap", "1.5"], "argument --overlap: 1.5 is out of range; accepted: 0 to 1"),
    (["simulate", "--overlap-until", "-1"], "argument --overlap-until: -1 is out of range; acce"),
    (["simulate", "--overlap-until", "many"], "argument --overlap-until: 'many' is not a whole"),
    (
        ["simulate", "--closure-checks", "2"],
        "argument --closure-checks: 2 is out of range; accepted",
    ),
    # a crowd's settings without a crowd: refused as `train` refuses them for one teacher
    (
        ["simulate", "--overlap", "0.5", "--teachers", "oracle"],
        "--overlap 0.5 acts on a crowd's answers; --teachers names no crowd ('oracle'): leave",
    ),
    (["simulate", "--overlap-until", "40"], "--overlap-until 40 acts on a crowd's answers; --te"),
    (
        ["simulate", "--closure-checks", "1", "--overlap-until", "0", "--teachers", "noisy"],
        "--overlap-until 0 and --closure-checks 1 act on a crowd's answers; --teachers names no",
    ),
    # reward-bench
    (["reward-bench", "pool", "--task", "nope", "--out", "p.npz"], "unknown task 'nope'"),
    (["reward-bench", "pool", "--out", "{dir}"], "pool file {dir} is a folder"),
    (["reward-bench", "pool", "--seed", "-1", "--out", "p.npz"], "argument --seed: -1 is out"),
    (["reward-bench", "pool", "--from-run", "{file}", "--out", "p.npz"], "no run directory at"),
    (["reward-bench", "run", "--pool", "missing.npz"], "pool missing.npz does not exist"),
    (["reward-bench", "run", "--pool", "m.npz", "--out", "{file}"], "pool m.npz does not exist"),
    (["reward-bench", "run", "--pool", "m.npz", "--seeds", "0"], "argument --seeds: 0 is out"),
    (["reward-bench", "run", "--pool", "m.npz", "--budgets", "50,25"], "argument --budgets: '50"),
    (["reward-bench", "run", "--pool", "m.npz", "--teachers", "oracle,,x"], "an empty teacher"),
    (["reward-bench", "run", "--pool", "m.npz", "--stops", "all,early"], "unknown stop rule 'ear"),
    (["reward-bench", "run", "--pool", "m.npz", "--stops", "x"], "accepted: all, asked, never"),
    (["reward-bench", "run", "--pool", "m.npz", "--augments", "off"], "accepted: full, checked, n"),
    (["reward-bench", "run", "--pool", "m.npz", "--orders", "sorted"], "unknown order 'sorted'; a"),
    (["reward-bench", "run", "--pool", "m.npz", "--orders", "x"], "accepted: uniform, collection"),
    (["reward-bench", "run", "--pool", "m.npz", "--weightings", "x"], "accepted: reliability, no"),
    (["reward-bench", "run", "--pool", "m.npz", "--overlap-until", "-1"], "--overlap-until: -1 i"),
    (["reward-bench", "run", "--pool", "m.npz", "--closure-checks", "2"], "--closure-checks: 2 is"),
    (["reward-bench", "run", "--pool", "{pool}", "--window-steps", "0"], "--window-steps: 0 is o"),
    (["reward-bench", "run", "--pool", "{pool}", "--window-steps", "50"], "ended within window 0"),
    (["reward-bench", "run", "--pool", "{pool}", "--window-steps", "150"], "2 complete windows"),
    (["reward-bench", "score", "x.jsonl", "--pool", "missing.npz"], "pool missing.npz does not"),
    (["reward-bench", "report", "{dir}"], "no rows in {dir}: give a folder that"),
    # dataset make, info; datasets given to label offline and reward-bench pool
    (["dataset", "info", "{dir}/nope"], "no Minari dataset at '{dir}/nope': give a dataset id"),
    (["dataset", "info", "missing-v0"], "no Minari dataset at 'missing-v0'"),
    (["dataset", "info", "{dataset_foreign}"], "does not name a seqrank task (no seqrank prov"),
    ([*MAKE, "--source", "expert", "--episodes", "2"], "unknown source 'expert'; accepted: random"),
    ([*MAKE, "--source", "scripted", "--episodes", "2"], "task dmc:cartpole_swingup has no scrip"),
    ([*MAKE, "--source", "random=x", "--episodes", "2"], "source 'random=x': share 'x' is not a n"),
    ([*MAKE, "--source", "random=-1", "--episodes", "2"], "its share must be a number > 0, got -1"),
    ([*MAKE, "--source", "random"], "--episodes is needed: only a run, as the one source, gives"),
    ([*MAKE, "--source", "random", "--source", "random", "--episodes", "1"], "gives no episode"),
    ([*MAKE, "--source", "random", "--episodes", "1", "--noise", "-1"], "--noise must be a numbe"),
    ([*MAKE, "--source", "run:{run}"], "run {run} has no checkpoint to take episodes from"),
    ([*MAKE, "--source", "run:{dir}/none"], "source run:{dir}/none: "),
    (
        [*RANDOM_ONE[:2], "--task", "walker_walk", "--source", "run:{run}", "--out", "{dir}/new"],
        "is a run of dmc:cartpole_swingup, not of walker_walk",
    ),
    ([*RANDOM_ONE, "--task", "nope", "--out", "{dir}/new"], "unknown task 'nope'"),
    ([*RANDOM_ONE, "--task", "cartpole_swingup", "--out", "{dataset}"], "dataset {dataset} alre"),
    ([*DATASET_PAGE, "{dataset}", "--task", "walker_walk"], "is of task dmc:cartpole_swingup, not"),
    ([*DATASET_PAGE, "{dataset_foreign}"], "does not name a seqrank task"),
    ([*DATASET_PAGE, "{dataset_foreign}", "--task", "walker_walk"], "observations of size 5 and "),
    ([*DATASET_PAGE, "{dataset_foreign}", "--task", "dmc:cartpole_swingup"], "no physics states"),
    (
        [*DATASET_PAGE, "{dataset}", "--questions", "10", "--segment-length", "30"],
        "needs 11 segments of 30 steps; dataset",
    ),
    (
        [*DATASET_PAGE, "{dataset}", "--segment-length", "31"],  # 30-step episodes, cut
        "--segment-length 31 is longer than the shortest episode of dataset made-v0 that ends "
        "without a terminal state (30 steps; a segment is padded only past a terminal state); "
        "accepted: 1 to 30",
    ),
    ([*DATASET_PAGE, "{dataset}", "--from", "{run}"], "--dataset gives the episodes to label: le"),
    ([*DATASET_PAGE, "{dataset}", "--episodes", "3"], "leave out --episodes"),
    ([*DATASET_PAGE, "missing-v0"], "no Minari dataset at 'missing-v0'"),
    (["label", "offline", "--port", "0"], "give the episodes to label: --from RUN, --task TASK o"),
    ([*POOL, "missing-v0"], "no Minari dataset at 'missing-v0'"),
    ([*POOL, "{dataset}"], "dataset {dataset} has 2 episodes; a pool needs at least 3"),
    ([*POOL, "{dataset}", "--from-run", "{run}"], "--from-dataset takes a dataset's episodes"),
    # watch, study-report
    (["watch", "{file}"], "no run directory at {file}"),
    (["watch", "{run}"], "{run} has no checkpoint yet"),
    (["watch", "{run}", "--size", "2000"], "argument --size: 2000 is out of range"),
    (["watch", "{run}", "--episodes", "0"], "argument --episodes: 0 is out of range"),
    (["watch", "{run}", "--out", "{file}"], "watch folder {file} is a file, not a folder"),
    (["study-report", "{file}"], "{file} holds no participant"),
    (["study-report", "{dir}", "--json", "x.json"], "{dir} holds no participant"),
    # no such command
    (["fly"], "invalid choice: 'fly'"),
    # no option is abbreviated (issue 45, item 5): a prefix is refused, not taken for another
    ([*TRAIN, "--schem", "root"], "seqrank train: error: unrecognized arguments: --schem root"),
    ([*TRAIN, "--annotator", "alice"], "seqrank train: error: unrecognized arguments: --annot"),
    (["reward-bench", "run", "--pool", "m.npz", "--seed", "3"], "reward-bench run: error: unrec"),
    # an unknown option is named by its own command; choices as typed (item 6)
    ([*TRAIN, "--nope"], "seqrank train: error: unrecognized arguments: --nope (see seqrank t"),
    (["sweep", "{toml}", "--nope"], "seqrank sweep: error: unrecognized arguments: --nope"),
    ([*TRAIN, "--scale", "huge"], "invalid choice: 'huge'; accepted: auto, paper, small (see"),
    ([*TRAIN, "--reward", "true", "--annotators", "alice,bob"], "--annotators names a team that"),
    ([*ONLINE, "--reward", "true"], "the labelling page asks a person questions; --reward 'tr"),
    # a task whose clips the page cannot show: refused before any address or folder (item 9)
    ([*ONLINE, "--task", "gym:Pendulum-v1"], "'gym:Pendulum-v1' cannot show clips: it has no"),
    ([*ONLINE, "--task", "gym:Pendulum-v1", "--dry-run"], "render_mode='rgb_array'"),
    (["label", "offline", "--task", "gym:Pendulum-v1", "--port", "0"], "cannot show clips"),
]


def snapshot(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in folder.rglob("*")}


@pytest.mark.parametrize(("args", "message"), CASES, ids=[" ".join(a) for a, _ in CASES])
def test_bad_input_is_one_line_exit_2_and_nothing_made(
    args, message, given, tmp_path, monkeypatch, capsys
):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    before = snapshot(Path(given["dir"]))
    code = main([arg.format(**given) for arg in args])
    err = capsys.readouterr().err
    assert code == 2, err
    assert message.format(**given) in err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith("seqrank") and "Traceback" not in err
    assert list(work.iterdir()) == []  # nothing in the working folder (default outputs)
    assert snapshot(Path(given["dir"])) == before  # nothing in the given folders


def test_each_front_end_names_the_settings_as_its_user_wrote_them(tmp_path, capsys):
    """One rule broken three ways: the command line names both settings as flags, a sweep
    file and the Python API as the setting names they take."""
    import seqrank

    code = main([*TRAIN, "--dry-run", "--knn-k", "2000", "--seed-steps", "1000"])
    assert code == 2
    assert "error: --knn-k 2000 must be smaller than --seed-steps 1000:" in capsys.readouterr().err

    spec = tmp_path / "sweep.toml"
    extra = "[overrides]\nknn_k = 2000\nseed_steps = 1000"
    spec.write_text(TOML.format(out=tmp_path / "sweep-out", extra=extra))
    assert main(["sweep", str(spec), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "knn_k 2000 must be smaller than seed_steps 1000:" in err and "--" not in err

    with pytest.raises(ValueError) as raised:
        seqrank.make_config("dmc:cartpole_swingup", knn_k=2000, seed_steps=1000)
    assert str(raised.value).startswith("knn_k 2000 must be smaller than seed_steps 1000:")


@pytest.mark.parametrize(
    ("saved", "message"),
    [
        ({"path": "reference", "precision": "tf32"}, "error: precision 'tf32' needs the fast"),
        ({"knn_k": 5000}, "error: knn_k 5000 must be smaller than seed_steps 300"),
    ],
)
def test_a_resumed_run_checks_its_saved_settings_and_names_them_not_flags(
    saved, message, given, capsys
):
    """The saved settings are checked as new ones are (a config.json edited by hand, or
    written under other rules); --resume refuses setting options, so the error names them
    as config.json does, and says where they are."""
    import json

    config_file = Path(given["run"]) / "config.json"
    config_file.write_text(json.dumps({**json.loads(config_file.read_text()), **saved}))
    assert main(["train", "--resume", given["run"]]) == 2
    err = capsys.readouterr().err
    assert message in err and f"saved in {given['run']}/config.json" in err
    assert "--precision" not in err and "--knn-k" not in err


def test_a_setting_error_reads_plainly_everywhere_and_survives_pickling():
    """The marks that let a command spell settings as flags never show: not in str, args or
    repr, nor after the trip a sweep worker's error makes between processes."""
    import pickle

    from seqrank.errors import SettingError, setting

    error = SettingError(f"{setting('knn_k')} 5 must be smaller than {setting('seed_steps')} 1")
    plain = "knn_k 5 must be smaller than seed_steps 1"
    assert str(error) == error.args[0] == plain and "\x00" not in repr(error)
    again = pickle.loads(pickle.dumps(error))
    assert str(again) == plain
    assert again.spelled(str.upper) == "KNN_K 5 must be smaller than SEED_STEPS 1"


@pytest.mark.parametrize("mode", ["online", "offline"])
def test_a_wrong_task_is_named_before_a_busy_port(mode, tmp_path, monkeypatch, capsys):
    import socket

    monkeypatch.chdir(tmp_path)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = str(busy.getsockname()[1])
        assert main(["label", mode, "--task", "walker_nope", "--port", port]) == 2
        assert "unknown --task 'walker_nope'" in capsys.readouterr().err
        assert main(["label", mode, "--task", "dmc:cartpole_swingup", "--port", port]) == 2
        assert "cannot listen there" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
