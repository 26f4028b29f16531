"""The Prefect tasks of the pipeline: thin wrappers over the stage functions in ``tasks/``, cached by content."""
