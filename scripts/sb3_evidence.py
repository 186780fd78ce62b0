"""One run of the SB3 evidence (issue 36, item 4): SB3's SAC (or PPO) from seqrank's
preferences, or on the true reward, for one (method, seed), into a run folder that
`seqrank report` reads beside seqrank's own runs (results/online-walker-cpu/).

    python scripts/sb3_evidence.py --out results/sb3 --method sequential --seed 0
    python scripts/sb3_evidence.py --out results/sb3 --method true-reward --seed 0
    python scripts/sb3_evidence.py --out results/sb3 --agent ppo --task gym:Pendulum-v1 \\
        --method sequential --seed 0 --steps 100000

A run trains in chunks of `--chunk` steps (an evaluation after each, then agent, replay
buffer and feedback saved): rerun the same command after a stop to continue it; a finished
run is skipped. Sizes match the small preset: SAC 256 x 2, batch 256, learning rate 5e-4,
tau 0.005, target every 2 updates, initial temperature 0.1, `seed_steps` random steps
(SB3 has one learning rate, so the temperature's is 5e-4, not seqrank's 1e-4).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3 import PPO, SAC

from seqrank.config import resolve_config
from seqrank.envs import make_env
from seqrank.sb3 import PreferenceFeedback, PreferenceReplayBuffer
from seqrank.sb3.envs import task_vec_env
from seqrank.training.state import episode_seed

METHODS = ("pairwise", "sequential", "root", "ranked", "true-reward")


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--method", choices=METHODS, required=True)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--agent", choices=("sac", "ppo"), default="sac")
    parser.add_argument("--task", default="walker_walk")
    parser.add_argument("--steps", type=int, default=60_000)
    parser.add_argument("--max-feedback", type=int, default=100)
    parser.add_argument("--chunk", type=int, default=10_000, help="steps between evaluations")
    parser.add_argument("--chunks", type=int, default=0, help="at most this many now (0: all)")
    parser.add_argument("--tiny", action="store_true", help="CI sizes (a test of the script)")
    return parser.parse_args(argv)


def settings_of(args: argparse.Namespace) -> dict[str, Any]:
    values: dict[str, Any] = {"steps": args.steps, "seed": args.seed, "device": "cpu"}
    values["max_feedback"] = args.max_feedback
    if args.tiny:
        values.update(seed_steps=100, unsup_steps=200, reward_batch=10, feedback_frequency=200)
        values.update(segment_length=10, reward_epochs=5, heldout_pairs=50, eval_episodes=1)
    if args.agent == "ppo":  # PEBBLE's entropy pre-training is for off-policy agents
        values["unsup_steps"] = 0
    return values


def run_config(args: argparse.Namespace) -> dict[str, Any]:
    """What the run folder's config.json says (the fields `seqrank report` reads)."""
    values = settings_of(args)
    if args.method == "true-reward":
        values = {k: v for k, v in values.items() if k == "steps" or k in ("seed", "device")}
        values["reward"] = "true"
    else:
        values["scheme"] = args.method
    config = resolve_config(args.task, "small", values).as_dict()
    config["backbone"] = f"sb3-{args.agent}"
    return config


def agent_options(args: argparse.Namespace, config: dict[str, Any]) -> dict[str, Any]:
    if args.agent == "ppo":  # rl-baselines3-zoo's tuned values for Pendulum-v1, one env
        if args.tiny:
            return {"n_steps": 256}
        return {
            "n_steps": 1024,
            "gae_lambda": 0.95,
            "gamma": 0.9,
            "n_epochs": 10,
            "ent_coef": 0.0,
            "learning_rate": 1e-3,
            "clip_range": 0.2,
            "use_sde": True,
            "sde_sample_freq": 4,
        }
    width = 32 if args.tiny else config["hidden"]
    return {
        "policy_kwargs": {"net_arch": [width] * config["layers"]},
        "batch_size": 64 if args.tiny else config["batch"],
        "learning_rate": config["actor_lr"],
        "tau": config["tau"],
        "gamma": config["discount"],
        "target_update_interval": config["target_update_every"],
        "ent_coef": f"auto_{config['init_temperature']}",
        "learning_starts": config["seed_steps"],
        "replay_buffer_class": PreferenceReplayBuffer,  # pre-training's state-entropy reward
    }


def evaluate(model: Any, task: str, seed: int, index: int, episodes: int) -> dict[str, Any]:
    """Deterministic episodes on the true reward, seeded as seqrank's evaluations."""
    env = make_env(task, seed)
    returns, successes = [], []
    for i in range(episodes):
        obs, _ = env.reset(seed=episode_seed(seed, 1, index, i))
        total, success, done = 0.0, False, False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            total, success = total + float(reward), success or bool(info["success"])
            done = terminated or truncated
        returns.append(total)
        successes.append(success)
    return {
        "eval_return": float(np.mean(returns)),
        "eval_return_std": float(np.std(returns)),
        "eval_success_rate": 100.0 * float(np.mean(successes)),
    }


class Job:
    """The run folder: config.json, metrics.jsonl, summary.json when finished, and the
    state a stopped run continues from (agent, replay buffer, feedback, progress.json)."""

    def __init__(self, args: argparse.Namespace):
        self.args, self.config = args, run_config(args)
        name = f"{args.method}_sb3-{args.agent}_{self.config['teacher']}_seed{args.seed}"
        if args.method == "true-reward":
            name = f"true-reward_sb3-{args.agent}_seed{args.seed}"
        self.folder = args.out / "runs" / args.task.replace(":", "-") / name
        self.kind = SAC if args.agent == "sac" else PPO

    def progress(self) -> dict[str, Any]:
        path = self.folder / "progress.json"
        return json.loads(path.read_text()) if path.exists() else {"step": 0, "episodes": [0]}

    def start(self) -> tuple[Any, PreferenceFeedback | None, Any]:
        args, learned = self.args, self.args.method != "true-reward"
        saved = self.progress()["step"] > 0
        feedback = None
        if learned:
            if saved:
                feedback = PreferenceFeedback.load(self.folder / "feedback")
            else:
                settings = settings_of(args)
                settings.pop("eval_episodes", None)
                pretrain = False if args.agent == "ppo" else None
                feedback = PreferenceFeedback(
                    args.task, scheme=args.method, scale="small", pretrain=pretrain, **settings
                )
            env = feedback.env
        else:
            env = task_vec_env([make_env(args.task, args.seed)], args.seed)
            env.envs[0].env.next_episode = self.progress()["episodes"][0]  # type: ignore[attr-defined]
        if saved:
            model = self.kind.load(self.folder / "agent", env=env)
            if self.kind is SAC:
                model.load_replay_buffer(self.folder / "buffer")
        else:
            model = self.kind("MlpPolicy", env, seed=args.seed, **agent_options(args, self.config))
        return model, feedback, env

    def save(self, model: Any, feedback: PreferenceFeedback | None, env: Any, step: int) -> None:
        model.save(self.folder / "agent")
        if self.kind is SAC:
            model.save_replay_buffer(self.folder / "buffer")
        if feedback is not None:
            feedback.save(self.folder / "feedback")
            episodes = [e.next_episode for e in feedback.state.seeded]
        else:
            episodes = [env.envs[0].env.next_episode]
        (self.folder / "progress.json").write_text(json.dumps({"step": step, "episodes": episodes}))


def run(argv: list[str] | None = None) -> str:
    args = parse(argv)
    job = Job(args)
    if (job.folder / "summary.json").exists():
        return f"{job.folder}: finished already"
    job.folder.mkdir(parents=True, exist_ok=True)
    (job.folder / "config.json").write_text(json.dumps(job.config, indent=2, default=str))
    model, feedback, env = job.start()
    step, done_now = job.progress()["step"], 0
    episodes = int(job.config["eval_episodes"])
    while step < args.steps and (not args.chunks or done_now < args.chunks):
        chunk = min(args.chunk, args.steps - step)
        model.learn(chunk, callback=feedback, reset_num_timesteps=step == 0)
        step, done_now = step + chunk, done_now + 1
        row = {
            "step": step,
            "kind": "eval",
            **evaluate(model, args.task, args.seed, step, episodes),
        }
        with (job.folder / "metrics.jsonl").open("a") as metrics:
            metrics.write(json.dumps(row) + "\n")
        job.save(model, feedback, env, step)
    if step < args.steps:
        return f"{job.folder}: stopped at step {step}; run the same command to continue"
    rows = [json.loads(line) for line in (job.folder / "metrics.jsonl").read_text().splitlines()]
    if feedback is not None:  # the sessions' rows, for the report's feedback columns
        with (job.folder / "metrics.jsonl").open("a") as metrics:
            metrics.writelines(json.dumps(r, default=float) + "\n" for r in feedback.metrics)
    summary = {"task": args.task, "steps": step, "final_eval_return": rows[-1]["eval_return"]}
    (job.folder / "summary.json").write_text(json.dumps(summary, indent=2))
    return f"{job.folder}: finished, eval return {rows[-1]['eval_return']:.1f}"


if __name__ == "__main__":
    print(run(sys.argv[1:]))
