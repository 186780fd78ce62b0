"""Reward learning: the preference-trained ensemble and the pre-training entropy reward."""
