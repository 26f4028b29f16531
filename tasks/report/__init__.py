"""Run reports: HTML with plots, the axes as an MCAP of scene markers, and the Prefect artifacts."""
