"""Agents: the contract the training loop relies on, SAC, DQN and MRN."""
