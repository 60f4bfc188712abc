"""The browser player: ``view`` (``convert OUT.html`` is in :mod:`.scenes`)."""

from __future__ import annotations

import click

from ..files.signals import consume_signals
from ..server import ViewServer, can_open_browser
from ._base import library_errors, main, notes, options


@main.command()
@click.argument("files", metavar="FILE...", nargs=-1, required=True, type=click.Path(dir_okay=False))
@options(
    click.option("--port", type=click.IntRange(0, 65535), default=0,
                 help="Port on 127.0.0.1 [default: a free one]."),
    click.option("--no-open", is_flag=True, help="Do not open a browser; just print the address."),
    click.option("--durations", metavar="D0,D1,...",
                 help="Each segment's share of the clip's timeline, e.g. its frames [default: equal shares]."),
)
@library_errors
def view(files, port, no_open, durations):
    """Play FILE in the browser: serves the player page and the scene on 127.0.0.1 only.

    Several FILEs play as the segments of one clip. A PLY, .splat or .zst input is
    converted in memory first. Stop with Ctrl-C.

    \b
    Example:
      splatconv view scene.splatv
      splatconv view seg0.splatv seg1.splatv seg2.splatv --no-open
    """
    server = ViewServer(files, port=port, durations=durations)
    try:
        notes(server.notes)
        click.echo(f"serving {', '.join(files)} at {server.url} (Ctrl-C to stop)")
        opening = not no_open and can_open_browser()
        if not no_open and not opening:
            notes(["no display to open a browser on: open the address above in a browser"])
        server.serve(open_browser=opening)
    except KeyboardInterrupt:
        consume_signals()  # Ctrl-C just before serving began: the same clean stop
    finally:
        server.close()
