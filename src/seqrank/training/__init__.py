"""Training: the PEBBLE / MRN loop as named phases, evaluation, run directories."""
