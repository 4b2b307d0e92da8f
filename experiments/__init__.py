"""Experiment runtime: protocols parsed into trial lists and presented with PsychoPy."""
