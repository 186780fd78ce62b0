"""seqrank: reinforcement learning from human preferences with sequential and root
pairwise comparison and transitive label augmentation (SeqRank, NeurIPS 2023)."""

__version__ = "0.1.0"
