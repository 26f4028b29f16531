"""The recording contract (``../shared/RECORDING.md``): writing demonstrations and loading ingested ones."""
