"""Stable-Baselines3's PPO on a Gymnasium task of your own making, from preferences:
sequential comparisons of a scripted teacher that errs 10% of the time (B-Pref's
`mistake`), with noise-aware augmentation. PPO gets the learned reward at rollout time.

    python examples/sb3_ppo_gym.py                       # Pendulum-v1, 100 000 steps
    python examples/sb3_ppo_gym.py --steps 1200 --tiny   # seconds (CI)
"""

from __future__ import annotations

import argparse

import gymnasium as gym
from stable_baselines3 import PPO
from stable_baselines3.common.evaluation import evaluate_policy

from seqrank.sb3 import PreferenceFeedback


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--tiny", action="store_true", help="CI sizes")
    args = parser.parse_args()
    budget = (
        dict(max_feedback=20, reward_batch=10, feedback_frequency=400, reward_epochs=5)
        if args.tiny
        else dict(max_feedback=200, reward_batch=20, feedback_frequency=8_000)
    )
    feedback = PreferenceFeedback(
        gym.make("Pendulum-v1"),  # any Gymnasium env with Box spaces and a time limit
        scheme="sequential",
        teacher="mistake",
        augment="checked",
        pretrain=False,  # PEBBLE's entropy pre-training is for off-policy agents
        seed_steps=200,
        segment_length=25,
        steps=args.steps,
        device="cpu",
        **budget,
    )
    n_steps = 200 if args.tiny else 2048
    model = PPO("MlpPolicy", feedback.env, n_steps=n_steps, batch_size=50, seed=0)
    model.learn(args.steps, callback=feedback)
    # the agent acts in feedback.env's space: a gymnasium.Env's actions rescaled to [-1, 1]
    evaluation = gym.wrappers.RescaleAction(gym.make("Pendulum-v1"), -1.0, 1.0)
    true_return, _ = evaluate_policy(model, evaluation, n_eval_episodes=3)
    c = feedback.run.counters
    print(f"asked {c.asked}, inferred {c.inferred}; true return {true_return:.1f}")


if __name__ == "__main__":
    main()
