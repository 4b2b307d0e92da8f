"""Data tables shipped with the stimulus engine (landmark orderings)."""
