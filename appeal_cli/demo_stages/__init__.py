"""Demo stages: each module defines ``STAGE = appeal.demo.DemoStage(...)``.

Orders: 0-99 set-up, 100s stimuli, 200s experiments, 300s analysis.
"""
