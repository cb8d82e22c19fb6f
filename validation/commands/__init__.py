"""The ``synptv`` subcommands: one module per command, its parser beside the code that
runs it (:mod:`validation.cli` assembles them)."""
