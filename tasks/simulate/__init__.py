"""Simulated execution of task descriptors in pybullet (issue 7; paper Section V-A)."""
