"""One module per ``pbd`` command: ``run(args) -> int`` (its arguments are in ``flows.cli_args``)."""
