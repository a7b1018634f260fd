"""CLI sub-commands, one module each (``NAME``, ``HELP``, ``add_arguments``, ``run``; ``ORDER`` sorts --help)."""
