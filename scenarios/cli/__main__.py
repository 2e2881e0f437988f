"""``python -m scenarios.cli``: the ``hilnav`` command line."""

from scenarios.cli.app import main

main()
