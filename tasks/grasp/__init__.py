"""Grasp planning (G of the descriptor): a Barrett BH8-280 hand and GraspIt!-style eigengrasp planning."""
