"""Sweeps: a grid of training runs from one file, on local processes or Ray."""
