"""Asking questions and learning from the answers: schemes, closure, teachers."""
