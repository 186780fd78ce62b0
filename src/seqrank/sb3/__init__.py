"""seqrank's feedback for Stable-Baselines3 agents (`pip install 'seqrank[sb3]'`):
`PreferenceFeedback` is an SB3 callback whose `env` gives the agent the learned reward;
`PreferenceReplayBuffer`, an off-policy agent's `replay_buffer_class`, gives its batches the
state-entropy reward while it pre-trains. docs/guides/sb3.md."""

from seqrank.sb3.callback import PreferenceFeedback
from seqrank.sb3.replay import PreferenceReplayBuffer

__all__ = ["PreferenceFeedback", "PreferenceReplayBuffer"]
