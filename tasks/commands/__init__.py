"""One module per ``pbd`` command: ``add_arguments(parser)`` and ``run(args) -> int``; light imports only."""
