"""Segmentation of marker trajectories into contiguous time spans (change points, or the paper's spectral)."""
