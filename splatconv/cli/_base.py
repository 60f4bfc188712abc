"""The ``splatconv`` group and what every command shares: error mapping, option types, option stacks."""

from __future__ import annotations

import functools
import math
import os

import click

from .. import __version__
from ..errors import SplatconvError, UsageError
from ..files.signals import exit_on_signals
from ..io import COLOR_MODES, noting_undrawable
from ..wording import plural
from ..zstd import DEFAULT_MAX_DECOMPRESSED, MAX_DECOMPRESSED_ENV, parse_byte_size, set_max_decompressed
from ._progress import progress_for


class Failure(click.ClickException):
    """One ``Error: ...`` line with a chosen exit code."""

    def __init__(self, message: str, exit_code: int = 1):
        super().__init__(message)
        self.exit_code = exit_code


def library_errors(fn):
    """Map library and OS errors to one-line click errors (usage errors exit 2)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except UsageError as e:
            raise Failure(str(e), 2) from None
        except SplatconvError as e:
            raise Failure(str(e), 1) from None
        except OSError as e:
            where = f"{e.filename}: " if e.filename else ""
            raise Failure(f"{where}{e.strerror or e}", 1) from None
        except MemoryError:
            raise Failure("out of memory", 1) from None

    return wrapper


class FiniteFloat(click.ParamType):
    """A float option that must be finite (and, with ``positive``, above zero).

    NaN compares false with everything, so ``--min-psnr nan`` would pass every
    frame and ``--time nan`` would draw nothing meaningful: refuse them as usage errors.
    """

    name = "float"

    def __init__(self, positive: bool = False):
        self.positive = positive

    def convert(self, value, param, ctx):
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number.", param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        if self.positive and not number > 0:
            self.fail(f"{value!r} is not a positive number.", param, ctx)
        return number


FINITE = FiniteFloat()
POSITIVE = FiniteFloat(positive=True)


def options(*decorators):
    """Apply click options so that ``--help`` lists them in the order given."""

    def apply(fn):
        for decorator in reversed(decorators):
            fn = decorator(fn)
        return fn

    return apply


def color_option():
    return click.option("--color", type=click.Choice(COLOR_MODES), default="auto", show_default=True,
                        help="Read PLY f_dc_0..2 as RGB (Spacetime Gaussians lite) or as SH degree 0 (3DGS); "
                             "auto picks by the variant.")


def quiet_option():
    return click.option("--quiet", "-q", is_flag=True,
                        help="No progress bar (there is none either when stderr is not a terminal).")


def force_option(what: str = "OUTPUT"):
    return click.option("--force", is_flag=True, help=f"Replace {what} if it exists (never an input).")


def notes(lines) -> None:
    """Echo lossy or noteworthy steps to stderr as ``note:`` lines."""
    for line in lines:
        click.echo(f"note: {line}", err=True)


def wrote(path, report) -> None:
    """Echo ``wrote PATH: N splats, B bytes`` for a file written."""
    click.echo(f"wrote {path}: {plural(report.count, 'splat')}, {os.path.getsize(path):,} bytes")


def progress(quiet: bool):
    """The progress reporter for a command: a bar on a terminal's stderr unless ``quiet``."""
    return progress_for(quiet)


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


class _UndrawableNote:
    """Echoes the library's note on a scene read with many undrawable splats: once a command (the
    first such scene), and not when the command was asked to ``--drop-undrawable`` them."""

    def __init__(self):
        self.shown = False

    def __call__(self, line: str) -> None:
        ctx = click.get_current_context(silent=True)
        if self.shown or (ctx is not None and ctx.params.get("drop_undrawable")):
            return
        self.shown = True
        notes([line])


#: ``splatconv`` alone shows the help (click 8.2 and later raise this for it).
_HELP_WITHOUT_ARGUMENTS = getattr(click.exceptions, "NoArgsIsHelpError", ())


class _Commands(click.Group):
    """The ``splatconv`` group: click's own usage errors (a bad option value, a missing
    argument, an unknown command) print one ``Error:`` line like every other error,
    not the usage block before it."""

    def make_context(self, info_name, args, parent=None, **extra):
        try:
            return super().make_context(info_name, args, parent, **extra)
        except _HELP_WITHOUT_ARGUMENTS:
            raise
        except click.UsageError as e:
            raise _one_line(e) from None

    def invoke(self, ctx):
        try:
            with noting_undrawable(_UndrawableNote()):
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
    splaTV's .splatv.

    \b
    Example:
      splatconv convert scene.ply scene.splatv
      splatconv info scene.splatv
    """
    exit_on_signals()  # SIGTERM, SIGHUP: clean up part and temporary files as Ctrl-C does
