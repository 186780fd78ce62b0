"""Train from a custom feedback source: a judge function that compares two segments.

    python examples/train_with_a_judge.py                 # a short cartpole run
    python examples/train_with_a_judge.py --steps 60000 --task walker_walk

The judge here prefers the segment whose true reward is larger, as a script would; put a
model that judges clips, or any interface, in its place. It receives `seqrank.Segment`s
(observations, actions and the simulator's rewards) and returns a `seqrank.Answer`.
"""

from __future__ import annotations

import argparse

import seqrank


def judge(first: seqrank.Segment, second: seqrank.Segment) -> seqrank.Answer:
    difference = first.rewards.sum() - second.rewards.sum()
    if abs(difference) < 1e-6:
        return seqrank.Answer.EQUAL
    return seqrank.Answer.FIRST if difference > 0 else seqrank.Answer.SECOND


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--task", default="dmc:cartpole_swingup")
    parser.add_argument("--steps", type=int, default=2_500)
    parser.add_argument("--out", default="seqrank-out/examples/judge")
    args = parser.parse_args()
    tiny = (
        {}
        if args.steps >= 60_000
        else {
            "seed_steps": 500,
            "unsup_steps": 500,
            "feedback_frequency": 500,
            "max_feedback": 30,
            "reward_batch": 10,
            "hidden": 64,
            "batch": 64,
            "reward_epochs": 10,
            "eval_every": 500,
            "eval_episodes": 1,
            "heldout_pairs": 50,
        }
    )
    config = seqrank.make_config(args.task, "small", steps=args.steps, device="cpu", **tiny)
    obs_dim = seqrank.make_env(args.task).obs_dim
    summary = seqrank.train(config, args.out, source=seqrank.JudgeSource(judge, obs_dim))
    print(
        f"asked {summary['asked']}, inferred {summary['inferred']}; "
        f"final return {summary['final_eval_return']:.1f}; run in {args.out}"
    )


if __name__ == "__main__":
    main()
