"""``python -m splatconv`` and the ``splatconv`` command: the signals first, then the command line.

Importing the command line (click, zstandard) and a command (numpy, ...) takes a
moment; a Ctrl-C, SIGTERM or SIGHUP in it ends the run as it does later on, with
no traceback, because the handlers are set before anything else is imported.
A run a signal ended leaves without waiting for its threads
(:func:`~splatconv.files.signals.exit_at_once`).
"""

import sys

from .files.heap import one_arena
from .files.signals import asked_to_end, exit_at_once, exit_on_signals, hold_signals, status_for_signal


def run() -> None:
    """Run the ``splatconv`` command line (the console script's entry point)."""
    exit_on_signals()
    one_arena()  # before any helper thread: what one phase of a run frees, the next takes
    try:
        from .cli import main  # the one late import: after the handlers are set
    except KeyboardInterrupt:
        sys.stderr.write("\nAborted!\n")  # what click says of a Ctrl-C once it runs
        sys.exit(1)
    try:
        main(prog_name="splatconv")
    except BaseException as e:
        if not asked_to_end():
            raise
        hold_signals()  # a second signal from here on is only remembered: the run is ending
        # The clean-ups ran on the way here. A signal that landed in the threading
        # module's own code can surface as its RuntimeError, and leave a thread
        # that never ends: the signal's status, no traceback, no wait.
        if not isinstance(e, SystemExit) and status_for_signal() == 1:
            sys.stderr.write("\nAborted!\n")  # click says it of a Ctrl-C it caught itself
        exit_at_once(status_for_signal())


if __name__ == "__main__":
    run()
