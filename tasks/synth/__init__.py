"""Simulated demonstration recordings of the built-in scenes (``pbd synth``, issue 3)."""
