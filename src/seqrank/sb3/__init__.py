"""seqrank's feedback for Stable-Baselines3 agents (`pip install 'seqrank[sb3]'`):
`PreferenceFeedback` is an SB3 callback whose `env` gives the agent the learned reward.
docs/guides/sb3.md."""

from seqrank.sb3.callback import PreferenceFeedback

__all__ = ["PreferenceFeedback"]
