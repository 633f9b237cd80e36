"""The ``rollfric`` command: one entry point, one module per subcommand."""
