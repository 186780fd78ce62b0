"""seqrank's SAC against Stable-Baselines3's, both on the true reward, at matched sizes.

    .venv/bin/pip install -e '.[compare]'      # Stable-Baselines3, for this script only
    .venv/bin/python scripts/sac_vs_sb3.py run --runs seqrank-out/sac-vs-sb3
    .venv/bin/python scripts/sac_vs_sb3.py report --runs seqrank-out/sac-vs-sb3 \
        --out results/sac-vs-sb3

`run` trains every (task, implementation, seed) that has no result yet, `--workers` at a
time, each on one thread; a killed command continues where it stopped (seqrank runs resume
from their checkpoint, SB3 runs from their last evaluation's saved model and buffer). The
seqrank side is `seqrank train --reward true` itself, so what is measured is the package's
own loop. Both sides: 256 x 2 networks, batch 256, learning rate 5e-4, discount 0.99, soft
target update tau 0.005 every 2 updates, 1 000 random steps first, one update per step,
temperature starting at 0.1 with target entropy -|A|, and the same deterministic evaluation
episodes (`--eval-episodes` every `--eval-every` steps, seeded alike). What differs is each
implementation's own choice: seqrank follows B-Pref (temperature learning rate 1e-4,
orthogonal initialisation, log-std in [-5, 2]); SB3 its defaults (temperature learning rate
= the shared 5e-4, PyTorch's initialisation, log-std in [-20, 2]). `--variant NAME:K=V,...`
adds a seqrank run with other `seqrank train` settings, to find what explains a gap.

`report` writes `table.md` (IQM of the final return per task and implementation with a 95%
bootstrap interval), `curves.png` (mean curves with 95% intervals) and `curves.json` (every
run's evaluation curve) in `--out`.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

SHARED = {"hidden": 256, "layers": 2, "batch": 256, "lr": 5e-4, "temperature": 0.1}


@dataclass(frozen=True)
class Job:
    task: str
    impl: str  # seqrank, sb3, or seqrank-<variant>
    seed: int
    settings: tuple[tuple[str, str], ...]  # extra `seqrank train` settings of a variant

    @property
    def name(self) -> str:
        return f"{self.task}/{self.impl}_seed{self.seed}"


def seqrank_command(job: Job, args: argparse.Namespace, folder: Path) -> list[str]:
    if (folder / "config.json").exists():
        return [sys.executable, "-m", "seqrank", "train", "--resume", str(folder), "--quiet"]
    settings = {
        "task": job.task,
        "reward": "true",
        "scale": "small",
        "device": "cpu",
        "seed": job.seed,
        "steps": args.steps,
        "hidden": SHARED["hidden"],
        "layers": SHARED["layers"],
        "batch": SHARED["batch"],
        "actor_lr": SHARED["lr"],
        "critic_lr": SHARED["lr"],
        "init_temperature": SHARED["temperature"],
        "target_update_every": 2,
        "seed_steps": 1000,
        "eval_every": args.eval_every,
        "eval_episodes": args.eval_episodes,
        "checkpoint_every": args.eval_every,
        **dict(job.settings),
    }
    options = [f"--{k.replace('_', '-')}={v}" for k, v in settings.items()]
    return [sys.executable, "-m", "seqrank", "train", *options, "--out", str(folder), "--quiet"]


def seqrank_curve(folder: Path) -> list[tuple[int, float]] | None:
    if not (folder / "summary.json").exists():
        return None
    rows = [json.loads(line) for line in (folder / "metrics.jsonl").read_text().splitlines()]
    return [(r["step"], r["eval_return"]) for r in rows if r["kind"] == "eval"]


def run_job(job: Job, args: argparse.Namespace) -> str:
    folder = args.runs / job.name
    result = folder / "curve.json"
    if result.exists():
        return f"{job.name}: done before"
    folder.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    if job.impl == "sb3":
        command = [sys.executable, __file__, "sb3-run", "--folder", str(folder)]
        command += ["--task", job.task, "--seed", str(job.seed), "--steps", str(args.steps)]
        command += ["--eval-every", str(args.eval_every)]
        command += ["--eval-episodes", str(args.eval_episodes)]
    else:
        command = seqrank_command(job, args, folder / "seqrank")
    with (folder / "log.txt").open("a") as log:
        done = subprocess.run(command, env=env, stdout=log, stderr=subprocess.STDOUT, check=False)
    if done.returncode != 0:
        return f"{job.name}: FAILED (exit {done.returncode}, see {folder / 'log.txt'})"
    if job.impl != "sb3":
        curve = seqrank_curve(folder / "seqrank")
        result.write_text(json.dumps({"curve": curve, "command": " ".join(command[1:])}))
    return f"{job.name}: finished"


def jobs(args: argparse.Namespace) -> list[Job]:
    impls: list[tuple[str, tuple[tuple[str, str], ...]]] = [("seqrank", ()), ("sb3", ())]
    for variant in args.variant:
        name, _, assignments = variant.partition(":")
        pairs = tuple(tuple(a.split("=", 1)) for a in assignments.split(",") if a)
        if not name or any(len(p) != 2 for p in pairs):
            raise SystemExit(f"--variant {variant!r}: give NAME:KEY=VALUE[,KEY=VALUE...]")
        impls.append((f"seqrank-{name}", pairs))  # type: ignore[arg-type]
    # seed by seed, so that the first finished runs already pair up
    return [
        Job(task, impl, seed, settings)
        for seed in range(args.seeds)
        for task in args.tasks
        for impl, settings in impls
    ]


def command_run(args: argparse.Namespace) -> None:
    todo = jobs(args)
    print(f"{len(todo)} runs, {args.workers} at a time, in {args.runs}", flush=True)
    with ThreadPoolExecutor(args.workers) as pool:
        for line in pool.map(lambda job: run_job(job, args), todo):
            print(line, flush=True)


# ---- the SB3 side (runs in its own process) --------------------------------------------
def command_sb3_run(args: argparse.Namespace) -> None:
    import torch
    from stable_baselines3 import SAC
    from stable_baselines3.common.callbacks import BaseCallback

    from seqrank.envs import make_env
    from seqrank.training.evaluation import evaluate_policy
    from seqrank.training.state import episode_seed

    torch.set_num_threads(1)
    folder: Path = args.folder
    env, eval_env = make_env(args.task, args.seed), make_env(args.task, args.seed)
    progress_path, model_path = folder / "progress.json", folder / "model.zip"
    progress: dict[str, Any] = {"curve": []}
    if progress_path.exists() and model_path.exists():  # resume from the last evaluation
        progress = json.loads(progress_path.read_text())
        model = SAC.load(model_path, env=env, device="cpu")
        model.load_replay_buffer(folder / "buffer.pkl")
    else:
        model = SAC(
            "MlpPolicy",
            env,
            learning_rate=SHARED["lr"],
            buffer_size=args.steps,
            learning_starts=1000,
            batch_size=SHARED["batch"],
            tau=0.005,
            gamma=0.99,
            train_freq=1,
            gradient_steps=1,
            ent_coef=f"auto_{SHARED['temperature']}",
            target_update_interval=2,
            policy_kwargs={"net_arch": [SHARED["hidden"]] * SHARED["layers"]},
            seed=args.seed,
            device="cpu",
        )

    class Policy:
        def act(self, obs: np.ndarray, deterministic: bool, generator: Any) -> np.ndarray:
            action, _ = model.predict(obs, deterministic=True)
            return np.asarray(action)

    class Evaluate(BaseCallback):  # type: ignore[misc]
        def _on_step(self) -> bool:
            step = self.num_timesteps
            if step % args.eval_every:
                return True
            k = len(progress["curve"])
            seeds = [episode_seed(args.seed, 1, k, i) for i in range(args.eval_episodes)]
            score = evaluate_policy(Policy(), eval_env, seeds, torch.Generator())
            progress["curve"].append((step, float(np.mean(score.returns))))
            model.save(model_path)
            model.save_replay_buffer(folder / "buffer.pkl")
            progress_path.write_text(json.dumps(progress))
            return True

    remaining = args.steps - model.num_timesteps
    model.learn(remaining, callback=Evaluate(), reset_num_timesteps=False)
    command = f"stable-baselines3 {__import__('stable_baselines3').__version__} SAC"
    (folder / "curve.json").write_text(json.dumps({**progress, "command": command}))
    for path in (model_path, folder / "buffer.pkl"):
        path.unlink(missing_ok=True)


# ---- the report ---------------------------------------------------------------------------
def command_report(args: argparse.Namespace) -> None:
    from seqrank.report.stats import iqm, stratified_bootstrap_ci

    results: dict[tuple[str, str], list[list[tuple[int, float]]]] = {}
    every: dict[str, Any] = {}
    for path in sorted(args.runs.glob("*/*/curve.json")):
        impl = path.parent.name.rsplit("_seed", 1)[0]
        record = json.loads(path.read_text())
        curve = [tuple(p) for p in record["curve"]]
        results.setdefault((path.parent.parent.name, impl), []).append(curve)  # type: ignore[arg-type]
        every[f"{path.parent.parent.name}/{path.parent.name}"] = record
    if not results:
        raise SystemExit(f"no finished runs under {args.runs}")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "curves.json").write_text(json.dumps(every, indent=1) + "\n")
    rng = np.random.default_rng(0)
    lines = [
        "| task | implementation | seeds | final return: IQM [95% CI] | mean ± std |",
        "|---|---|---|---|---|",
    ]
    for (task, impl), curves in sorted(results.items()):
        finals = np.array([c[-1][1] for c in curves])
        low, high = stratified_bootstrap_ci(
            lambda s: iqm(s["t"]), ({"t": finals},), args.bootstrap, rng
        )
        spread = f"{finals.std(ddof=1):.0f}" if len(finals) > 1 else "-"
        lines.append(
            f"| {task} | {impl} | {len(finals)} | {iqm(finals):.0f} [{low:.0f}, {high:.0f}] | "
            f"{finals.mean():.0f} ± {spread} |"
        )
    table = "\n".join(lines)
    print(table)
    _plot(results, args.out / "curves.png")
    (args.out / "table.md").write_text(table + "\n")
    print(f"wrote {args.out / 'table.md'} and {args.out / 'curves.png'}")


def _plot(results: dict[tuple[str, str], list[list[tuple[int, float]]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tasks = sorted({task for task, _ in results})
    figure, axes = plt.subplots(1, len(tasks), figsize=(5.5 * len(tasks), 4), squeeze=False)
    for axis, task in zip(axes[0], tasks, strict=True):
        for (t, impl), curves in sorted(results.items()):
            if t != task:
                continue
            length = min(len(c) for c in curves)
            steps = np.array([p[0] for p in curves[0][:length]])
            values = np.array([[p[1] for p in c[:length]] for c in curves])
            mean = values.mean(0)
            half = 1.96 * values.std(0, ddof=1) / np.sqrt(len(values)) if len(values) > 1 else 0
            (line,) = axis.plot(steps, mean, label=f"{impl} (n={len(values)})")
            axis.fill_between(steps, mean - half, mean + half, color=line.get_color(), alpha=0.2)
        axis.set_title(f"{task}: true reward, mean and 95% interval")
        axis.set_xlabel("environment steps")
        axis.set_ylabel("evaluation return")
        axis.grid(alpha=0.3)
        axis.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="train every run that has no result yet")
    run.add_argument("--runs", type=Path, default=Path("seqrank-out/sac-vs-sb3"))
    run.add_argument("--tasks", type=lambda t: t.split(","), default=["walker_walk", "cheetah_run"])
    run.add_argument("--seeds", type=int, default=5)
    run.add_argument("--steps", type=int, default=50_000)
    run.add_argument("--eval-every", type=int, default=10_000)
    run.add_argument("--eval-episodes", type=int, default=10)
    run.add_argument("--workers", type=int, default=2)
    run.add_argument("--variant", action="append", default=[], metavar="NAME:K=V,...")
    report = commands.add_parser("report", help="the table and the curves of finished runs")
    report.add_argument("--runs", type=Path, default=Path("seqrank-out/sac-vs-sb3"))
    report.add_argument("--out", type=Path, default=Path("results/sac-vs-sb3"))
    report.add_argument("--bootstrap", type=int, default=5000)
    sb3 = commands.add_parser("sb3-run", help="(internal) one Stable-Baselines3 run")
    for name, kind in (("folder", Path), ("task", str), ("seed", int), ("steps", int)):
        sb3.add_argument(f"--{name}", type=kind, required=True)
    sb3.add_argument("--eval-every", type=int, required=True)
    sb3.add_argument("--eval-episodes", type=int, required=True)
    args = parser.parse_args()
    {"run": command_run, "report": command_report, "sb3-run": command_sb3_run}[args.command](args)


if __name__ == "__main__":
    main()
