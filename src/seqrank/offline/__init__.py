"""Offline preference-based RL: a fixed dataset of episodes, labels over its segments, a
learned reward, and an offline learner (issue 47)."""
