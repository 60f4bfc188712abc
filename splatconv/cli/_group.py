"""The ``splatconv`` group: its options, its one-line usage errors, and its commands, loaded lazily.

Every run parses through this module, so it imports only click and what the group's own
options need. A command's module (and the library behind it: the renderer, the web
server, the operations) is imported when that command is resolved, never for ``--help``
or for another command; :data:`COMMANDS` is the table of contents that makes this possible.
"""

from __future__ import annotations

import importlib

import click

from .. import __version__
from ..files.signals import exit_on_signals
from ..zstd import DEFAULT_MAX_DECOMPRESSED, MAX_DECOMPRESSED_ENV, parse_byte_size, set_max_decompressed

#: Command name -> (module under ``splatconv.cli`` that defines it, its summary). The summary is
#: the first paragraph of the command's own help, declared here so that ``splatconv --help``
#: lists every command without importing any (a test checks that the two agree).
COMMANDS = {
    "bake": ("edit", "Write the scene as the viewer shows it at one time, as a static scene."),
    "convert": ("scenes", "Convert INPUT to OUTPUT; formats by extension (.ply, .splatv, .splatvq, .splat, .spz, "
                          ".sog, .glb, ...; any + .zst; .html: a player page)."),
    "diff": ("drawing", "Compare A and B: two images, or two scene files drawn the same way."),
    "info": ("facts", "Describe scene files: format, variant, count, texture, cameras, time range, bounds, "
                      "non-finite values and what is ignored."),
    "merge": ("edit", "Put several scenes in one file on the same timeline."),
    "render": ("drawing", "Render INPUT (.splatv or PLY) headlessly with the viewer's shader to OUTPUT."),
    "stats": ("facts", "Report sizes, zstd transport size and what a conversion loses."),
    "verify": ("drawing", "Check that CONVERTED still shows what SOURCE does."),
    "view": ("web", "Play FILE in the browser: serves the player page and the scene on 127.0.0.1 only."),
}


class Failure(click.ClickException):
    """One ``Error: ...`` line with a chosen exit code."""

    def __init__(self, message: str, exit_code: int = 1):
        super().__init__(message)
        self.exit_code = exit_code


def _max_decompressed(ctx, param, value):
    try:
        set_max_decompressed(None if value is None else parse_byte_size(value))
    except ValueError as e:
        raise click.BadParameter(str(e), ctx, param) from None


def _one_line(error: click.UsageError) -> Failure:
    """A click usage error as one ``Error: ...`` line (exit 2) that says where help is."""
    message = error.format_message().rstrip()
    if error.ctx is not None:
        message += ("" if message.endswith((".", "?", "!")) else ".") + f" See '{error.ctx.command_path} --help'."
    return Failure(message, error.exit_code)


#: ``splatconv`` alone shows the help (click 8.2 and later raise this for it).
_HELP_WITHOUT_ARGUMENTS = getattr(click.exceptions, "NoArgsIsHelpError", ())


class _Commands(click.Group):
    """The ``splatconv`` group.

    Click's own usage errors (a bad option value, a missing argument, an unknown command)
    print one ``Error:`` line like every other error, not the usage block before it.
    Commands are found in :data:`COMMANDS`: resolving one imports its module, whose
    ``@main.command()`` registers it; the help lists the declared summaries instead.
    """

    def list_commands(self, ctx):
        return sorted(set(COMMANDS) | set(self.commands))

    def get_command(self, ctx, cmd_name):
        if cmd_name in COMMANDS and cmd_name not in self.commands:
            importlib.import_module(f"{__package__}.{COMMANDS[cmd_name][0]}")
        return super().get_command(ctx, cmd_name)

    def format_commands(self, ctx, formatter):
        # click's own listing, with a stand-in carrying the declared summary for each command
        # not loaded yet: the same rows at any width, without importing the command.
        loaded = self.commands
        stand_ins = {name: click.Command(name, help=summary) for name, (_module, summary) in COMMANDS.items()}
        self.commands = {**stand_ins, **loaded}
        try:
            super().format_commands(ctx, formatter)
        finally:
            self.commands = loaded

    def make_context(self, info_name, args, parent=None, **extra):
        try:
            return super().make_context(info_name, args, parent, **extra)
        except _HELP_WITHOUT_ARGUMENTS:
            raise
        except click.UsageError as e:
            raise _one_line(e) from None

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except _HELP_WITHOUT_ARGUMENTS:
            raise
        except click.UsageError as e:
            raise _one_line(e) from None


@click.group(cls=_Commands, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="splatconv")
@click.option("--max-decompressed", metavar="SIZE", callback=_max_decompressed, expose_value=False,
              help=f"Largest size a .zst input may decompress to, and the memory the scene read from it may "
                   f"take, e.g. 8G (or set {MAX_DECOMPRESSED_ENV}) "
                   f"[default: {DEFAULT_MAX_DECOMPRESSED >> 30}G].")
def main():
    """Convert, check and preview 4D Gaussian-splatting scenes: Spacetime Gaussians and 3DGS PLY,
    splaTV's .splatv, and the static formats the field shares in (.spz, .sog, .glb, ...).

    \b
    Example:
      splatconv convert scene.ply scene.splatv
      splatconv info scene.splatv
    """
    exit_on_signals()  # SIGTERM, SIGHUP: clean up part and temporary files as Ctrl-C does


def commands() -> dict:
    """Every command by name, each loaded (this imports every command module): for generated
    documentation and tests, which need them all. ``main.commands`` holds only those loaded so far."""
    ctx = click.Context(main)
    return {name: main.get_command(ctx, name) for name in main.list_commands(ctx)}
