"""A person teaches a Stable-Baselines3 agent on seqrank's labelling page: open the address
it prints, watch the two clips, pick the better one. Training waits for each session's
answers (the first after the first episode), then carries on.

    python examples/sb3_human.py                          # SAC on walker_walk, 30 questions
    python examples/sb3_human.py --task dmc:cartpole_swingup --steps 1200 --tiny --port 0
"""

from __future__ import annotations

import argparse

from stable_baselines3 import SAC

from seqrank.labelling.app import ServerOptions
from seqrank.sb3 import PreferenceFeedback, PreferenceReplayBuffer


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--task", default="walker_walk")
    parser.add_argument("--steps", type=int, default=30_000)
    parser.add_argument("--port", type=int, default=8765, help="0: any free port")
    parser.add_argument("--tiny", action="store_true", help="CI sizes: 4 questions")
    parser.add_argument("--out", default="seqrank-out/examples/sb3-human")
    args = parser.parse_args()
    budget = dict(max_feedback=4, reward_batch=4, reward_epochs=5) if args.tiny else {}
    feedback = PreferenceFeedback(
        args.task,
        scheme="sequential",
        teacher="human",  # the person at the page
        label_dir=f"{args.out}/labels",  # answers are committed here before the page hears back
        page=ServerOptions(port=args.port, countdown_s=0.0 if args.tiny else 3.0),
        max_feedback=budget.get("max_feedback", 30),
        reward_batch=budget.get("reward_batch", 10),
        feedback_frequency=10_000,
        seed_steps=1_000,
        unsup_steps=100 if args.tiny else 4_000,
        steps=args.steps,
        device="cpu",
        reward_epochs=budget.get("reward_epochs", 30),
    )
    assert feedback.page is not None
    print(f"labelling page: {feedback.page.url}", flush=True)
    agent = dict(policy_kwargs=dict(net_arch=[64, 64]), batch_size=64) if args.tiny else {}
    # its buffer gives pre-training's batches the state-entropy reward
    model = SAC(
        "MlpPolicy", feedback.env, seed=0, replay_buffer_class=PreferenceReplayBuffer, **agent
    )
    try:
        model.learn(args.steps, callback=feedback)
        feedback.save(f"{args.out}/feedback")
    finally:
        feedback.close()
    print(f"answered {feedback.run.counters.answered}; saved in {args.out}")


if __name__ == "__main__":
    main()
