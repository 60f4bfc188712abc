"""What every command shares: error mapping, option types, option stacks (the group is in :mod:`._group`)."""

from __future__ import annotations

import functools
import math
import os

import click

from ..errors import SplatconvError, UsageError
from ..files.signals import check_signals
from ..io import COLOR_MODES, QUALITIES, noting_undrawable
from ..wording import plural
from ..zstd import DEFAULT_LEVEL, parse_byte_size
from ._group import Failure, main  # noqa: F401  (command modules import both from here)
from ._progress import progress_for


def library_errors(fn):
    """Map library and OS errors to one-line click errors (usage errors exit 2), and echo the
    library's note on a scene read with many undrawable splats (:class:`_UndrawableNote`).
    A command that a signal asked to end never returns as if it had not (:func:`check_signals`).

    Every command body is wrapped in this; the group is not, so that it loads no library."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            try:
                with noting_undrawable(_UndrawableNote()):
                    result = fn(*args, **kwargs)
            finally:
                # A signal whose exception was swallowed on the way, or turned into
                # another error, still ends the run as that signal.
                check_signals()
            return result
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


def quality_option():
    return click.option("--quality", type=click.Choice(QUALITIES),
                        help=f".splatvq OUTPUT: the quantizer's setting, trading size for fidelity "
                             f"(docs/formats.md) [default: {QUALITIES[0]}]. .html OUTPUT: embed the scene as "
                             f".splatvq at this setting, a compact page (without it: as the .splatv texture, or a "
                             f".splatvq INPUT with its own setting).")


class ByteSize(click.ParamType):
    """A size such as 5M, 512k or 1000000 (binary units; an optional B or iB)."""

    name = "size"

    def convert(self, value, param, ctx):
        if isinstance(value, int):
            return value
        try:
            return parse_byte_size(value)
        except ValueError as e:
            self.fail(str(e), param, ctx)


def proof_options():
    """``--min-psnr``, ``--max-bytes``, ``--best-effort``, ``--prune`` and ``--no-proof``: a compressed output
    that proves its quality."""
    return (
        click.option("--min-psnr", type=POSITIVE, metavar="DB",
                     help="A .splatvq OUTPUT proves its quality: it is written at the precision step (the "
                          "--quality setting, finer or coarser by half steps) whose worst frame reaches DB "
                          "against the scene it encodes, drawn as the viewer draws them from the header cameras, "
                          "views near them and splaTV's opening view at five times (fewer frames for a scene of "
                          "millions of splats); exit 1 if no step does. Default: the setting's floor, 45 dB for "
                          "default, 40 for small."),
        click.option("--max-bytes", type=ByteSize(), metavar="SIZE",
                     help="A .splatvq OUTPUT of at most SIZE bytes (e.g. 5M, binary units): the finest precision "
                          "step that fits (with --min-psnr, that also reaches DB); its quality is measured as "
                          "for --min-psnr and said."),
        click.option("--best-effort", is_flag=True,
                     help="When no step reaches the floor, write the best one measured and say how far short "
                          "it is."),
        click.option("--prune", is_flag=True,
                     help="Also leave out the drawable splats that add least to the proof's frames (ranked by "
                          "their blend weight over its views and times), as many as keep the worst frame at "
                          "the floor or above; a note and the file's header say how many. Without it every "
                          "drawable splat is kept."),
        click.option("--no-proof", is_flag=True,
                     help="Write a .splatvq OUTPUT at the --quality setting as named, without drawing it: "
                          "faster, and its quality unmeasured."),
    )


def quiet_option():
    return click.option("--quiet", "-q", is_flag=True,
                        help="No progress bar (there is none either when stderr is not a terminal).")


def page_options():
    """An .html OUTPUT's options: ``--fit`` and ``--no-poster`` (:class:`splatconv.publish.PageOptions`)."""
    return (
        click.option("--fit", is_flag=True,
                     help="For an .html OUTPUT: the page opens fitting the camera's whole view to the window "
                          "(fx and fy scaled as render --fit scales them) instead of keeping the camera's focal "
                          "lengths at any window size (splaTV's way). F, the fit button or #fit=1 switch it."),
        click.option("--no-poster", is_flag=True,
                     help="For an .html OUTPUT: no poster. By default the page's first frame is drawn headlessly "
                          "and shown until WebGL draws (embedded; with --external written beside the page as "
                          "OUT.poster.jpg and named for sharers by og:image)."),
    )


def force_option(what: str = "OUTPUT"):
    return click.option("--force", is_flag=True, help=f"Replace {what} if it exists (never an input).")


def zstd_option(what: str):
    return click.option("--zstd-level", type=click.IntRange(1, 22), default=None,
                        help=f"zstd level for {what} [default: {DEFAULT_LEVEL}].")


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
