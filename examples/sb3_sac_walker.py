"""Stable-Baselines3's SAC on walker_walk, taught by root pairwise comparisons of a
scripted oracle (seqrank's PEBBLE pieces on: entropy pre-training, critic reset).

    python examples/sb3_sac_walker.py                    # the README's run: 60 000 steps
    python examples/sb3_sac_walker.py --steps 1100 --tiny  # a minute on a CPU (CI)

The agent learns from the learned reward only; SB3's `rollout/ep_rew_mean` is the true
return (the environment's Monitor), and the folder `--out` keeps labels, reward model and
episodes (`PreferenceFeedback.load` continues from it).
"""

from __future__ import annotations

import argparse

from stable_baselines3 import SAC

from seqrank.sb3 import PreferenceFeedback, PreferenceReplayBuffer

# small enough for CI: the first session right after the first episode, 10 questions
TINY = dict(seed_steps=1_000, unsup_steps=50, reward_batch=10, reward_epochs=5, heldout_pairs=50)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--steps", type=int, default=60_000)
    parser.add_argument("--tiny", action="store_true", help="CI sizes (one short session)")
    parser.add_argument("--out", default="seqrank-out/examples/sb3-walker")
    args = parser.parse_args()
    sizes = dict(TINY, max_feedback=10) if args.tiny else dict(max_feedback=100)
    feedback = PreferenceFeedback(
        "walker_walk",
        scheme="root",
        teacher="oracle",
        feedback_frequency=10_000,
        steps=args.steps,
        device="cpu",
        **sizes,
    )
    agent = dict(policy_kwargs=dict(net_arch=[64, 64]), batch_size=64) if args.tiny else {}
    # its buffer gives pre-training's batches the state-entropy reward
    model = SAC(
        "MlpPolicy", feedback.env, seed=0, replay_buffer_class=PreferenceReplayBuffer, **agent
    )
    model.learn(args.steps, callback=feedback)
    feedback.save(args.out)
    c = feedback.run.counters
    print(f"asked {c.asked}, labelled pairs {len(feedback.labels)}, saved in {args.out}")


if __name__ == "__main__":
    main()
