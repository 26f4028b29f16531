"""Prefect flows: they only wire the tasks in ``tasks/`` and read like the pipeline picture in the README."""
