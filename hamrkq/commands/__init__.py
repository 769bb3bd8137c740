"""Subcommands of the ``hamrkq`` command line beyond ``list`` and ``show``."""
