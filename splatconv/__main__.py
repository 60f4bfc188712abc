"""``python -m splatconv`` and the ``splatconv`` command: the signals first, then the command line.

Importing the command line (click, zstandard) and a command (numpy, ...) takes a
moment; a Ctrl-C, SIGTERM or SIGHUP in it ends the run as it does later on, with
no traceback, because the handlers are set before anything else is imported.
"""

import sys

from .files.signals import exit_on_signals


def run() -> None:
    """Run the ``splatconv`` command line (the console script's entry point)."""
    exit_on_signals()
    try:
        from .cli import main  # the one late import: after the handlers are set
    except KeyboardInterrupt:
        sys.stderr.write("\nAborted!\n")  # what click says of a Ctrl-C once it runs
        sys.exit(1)
    main(prog_name="splatconv")


if __name__ == "__main__":
    run()
