"""The ``splatconv`` command: a thin click layer over the library.

Library errors become one ``Error: ...`` line: exit 1 for bad input, 2 for usage.
"""

from __future__ import annotations

import functools
import math
import os

import click

import splatconv
from splatconv.errors import SplatconvError, UsageError


class _Failure(click.ClickException):
    """One ``Error: ...`` line with a chosen exit code."""

    def __init__(self, message: str, exit_code: int = 1):
        super().__init__(message)
        self.exit_code = exit_code


def _library_errors(fn):
    """Map library and OS errors to one-line click errors."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except UsageError as e:
            raise _Failure(str(e), 2) from None
        except SplatconvError as e:
            raise _Failure(str(e), 1) from None
        except OSError as e:
            where = f"{e.filename}: " if e.filename else ""
            raise _Failure(f"{where}{e.strerror or e}", 1) from None
        except MemoryError:
            raise _Failure("out of memory", 1) from None

    return wrapper


class _FiniteFloat(click.ParamType):
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


_FINITE = _FiniteFloat()
_POSITIVE = _FiniteFloat(positive=True)


def _notes(notes) -> None:
    for note in notes:
        click.echo(f"note: {note}", err=True)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(splatconv.__version__, prog_name="splatconv")
def main():
    """Convert 4D Gaussian-splatting scenes between PLY (Spacetime Gaussians, 3DGS) and splaTV's .splatv."""


@main.command()
@click.argument("input_path", metavar="INPUT", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.argument("output_path", metavar="OUTPUT", type=click.Path(dir_okay=False))
@click.option("--external", is_flag=True,
              help="For an .html OUTPUT: write the scene beside the page (OUT.splatv) instead of "
                   "embedding it, for scenes too large to embed; the page must then be served over HTTP.")
@click.option("--compat", type=click.Choice(splatconv.COMPAT_MODES),
              help="splatv-js: texture bytes identical to splaTV's in-browser converter "
                   "(truncating halves). Default: accurate rounding.")
@click.option("--sort", type=click.Choice(splatconv.SORT_MODES),
              help="Record order: importance (largest, most opaque first, so the viewer can draw "
                   "while streaming; default for .splatv) or none (input order; default for .ply).")
@click.option("--cameras", "cameras", type=click.Path(dir_okay=False),
              help="A 3DGS / Spacetime Gaussians cameras.json to store in the output.")
@click.option("--color", type=click.Choice(splatconv.COLOR_MODES), default="auto", show_default=True,
              help="Read PLY f_dc_0..2 as RGB (Spacetime Gaussians lite) or as SH degree 0 (3DGS); "
                   "auto picks by the variant.")
@click.option("--force", is_flag=True, help="Replace OUTPUT if it exists (never the input).")
@click.option("--zstd-level", type=click.IntRange(1, 22), default=None,
              help="zstd level for a .zst OUTPUT, e.g. scene.splatv.zst [default: 19].")
@_library_errors
def convert(input_path, output_path, external, compat, sort, cameras, color, force, zstd_level):
    """Convert INPUT to OUTPUT; formats by extension (.ply, .splatv, either + .zst; .html writes a player page).

    Lossy steps (saturated halves, clamped colours, dropped properties) are
    reported as notes on stderr. OUTPUT is written atomically; a .zst OUTPUT is
    compressed while it is written. Several INPUTs make one .html page that plays
    them as the segments of one clip.

    Example: splatconv convert scene.ply scene.html
    """
    # Player pages for segment lists and --external: see splatconv.web.publish.
    if external or len(input_path) > 1:
        from splatconv.web.publish import publish

        if compat or sort or cameras or zstd_level:
            raise _Failure("--compat, --sort, --cameras and --zstd-level do not apply with --external "
                           "or several inputs", 2)
        report = publish(input_path, output_path, external=external, force=force)
        _notes(report.notes)
        for path, size in report.written:
            click.echo(f"wrote {path}: {size:,} bytes")
        return
    input_path = input_path[0]
    scene, report = splatconv.convert(input_path, output_path, compat=compat, sort=sort,
                                      cameras=cameras, color=color, force=force, zstd_level=zstd_level)
    _notes(scene.notes)
    _notes(report.notes)
    size = os.path.getsize(output_path)
    click.echo(f"wrote {output_path}: {report.count:,} splats, {size:,} bytes")


@main.command()
@click.argument("path", metavar="FILE", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the facts as JSON.")
@click.option("--color", type=click.Choice(splatconv.COLOR_MODES), default="auto", show_default=True,
              help="How to read PLY f_dc_0..2 (see convert).")
@_library_errors
def info(path, as_json, color):
    """Describe a scene file: format, variant, count, texture, cameras, time range,
    bounds, non-finite values and what is ignored."""
    from splatconv.formats import format_for
    from splatconv.report import info_text, to_json
    from splatconv.stats import describe

    module = format_for(path)
    scene = splatconv.read(path, color=color)
    data = describe(scene, path, module.NAME)
    click.echo(to_json(data) if as_json else info_text(data))


@main.command()
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.argument("output_path", metavar="OUTPUT", type=click.Path(dir_okay=False))
@click.option("--time", "time_", type=_FINITE, default=0.5, show_default=True,
              help="Scene time of the frame (the viewer plays 0..1).")
@click.option("--camera", type=int, help="Header camera to view from (default 0).")
@click.option("--view", help="Column-major view matrix as the viewer keeps it in its URL hash: "
                             "a JSON list of 16 numbers.")
@click.option("--size", help="Image size WxH. Default: the camera's, scaled down to at most 1280 wide, "
                             "fx and fy scaled along. An explicit size keeps the camera's fx and fy, as "
                             "the viewer does in a window of that size.")
@click.option("--fx", type=_POSITIVE, help="Focal length in pixels (default: the camera's; scaled with the "
                                           "default size).")
@click.option("--fy", type=_POSITIVE, help="Focal length in pixels (default: the camera's; scaled with the "
                                           "default size).")
@click.option("--frames", type=click.IntRange(1, 1000), default=1, show_default=True,
              help="Sweep N times over [0, 1]: an animated .gif or .webp, or a labelled "
                   "contact sheet for .png.")
@click.option("--reference", is_flag=True,
              help="Draw a PLY's attributes unquantized (float reference path) instead of as the "
                   ".splatv texture the viewer would get.")
@click.option("--color", type=click.Choice(splatconv.COLOR_MODES), default="auto", show_default=True,
              help="How to read PLY f_dc_0..2 (see convert).")
@click.option("--force", is_flag=True, help="Replace OUTPUT if it exists.")
@_library_errors
def render(input_path, output_path, time_, camera, view, size, fx, fy, frames, reference, color, force):
    """Render INPUT (.splatv or PLY) headlessly with the viewer's shader to OUTPUT.

    OUTPUT is a .png for one frame; with --frames N it is an animated .gif or
    .webp, or a .png contact sheet. The picture is the viewer's framebuffer:
    premultiplied colour over black.
    """
    from splatconv.render.commands import render_file

    if camera is not None and view is not None:
        raise _Failure("--camera and --view cannot be used together", 2)
    result = render_file(input_path, output_path, time=time_, camera=camera, view=view, size=size,
                         fx=fx, fy=fy, frames=frames, reference=reference, color=color, force=force)
    click.echo(result)


@main.command()
@click.argument("source", type=click.Path(dir_okay=False))
@click.argument("converted", required=False, type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON (keys in specs/stats.md).")
@click.option("--markdown", is_flag=True, help="Print the report as Markdown tables.")
@click.option("--zstd-level", type=click.IntRange(1, 22), default=None,
              help="zstd level for the transport sizes [default: 19].")
@click.option("--color", type=click.Choice(splatconv.COLOR_MODES), default="auto", show_default=True,
              help="How to read PLY f_dc_0..2 (see convert).")
@_library_errors
def stats(source, converted, as_json, markdown, zstd_level, color):
    """Report sizes, zstd transport size and what a conversion loses.

    With CONVERTED, compares it against SOURCE attribute by attribute; with SOURCE
    alone, reports what converting it to .splatv would give.
    """
    from splatconv.report import stats_markdown, stats_text, to_json
    from splatconv.stats import stats_report

    if as_json and markdown:
        raise _Failure("--json and --markdown cannot be used together", 2)
    data = stats_report(source, converted, zstd_level=zstd_level, color=color)
    click.echo(to_json(data) if as_json else stats_markdown(data) if markdown else stats_text(data))


def _view_options(times: str, cameras: str):
    """Camera, time and size options shared by verify and diff, with each command's defaults."""

    def decorate(fn):
        fn = click.option("--size", help="Image size WxH (default: each camera's, scaled down to at most 640 "
                                         "wide). fx and fy scale with the size (unlike render: these compare what "
                                         "the camera saw).")(fn)
        fn = click.option("--cameras", "cameras", default=None,
                          help=f"Cameras to draw from: 'all' or indices like 0,2 [default: {cameras}].")(fn)
        fn = click.option("--times", default=None, help=f"Comma-separated scene times [default: {times}].")(fn)
        fn = click.option("--min-psnr", type=_FINITE, default=40.0, show_default=True,
                          help="Every frame must reach this PSNR (dB) to pass; a finite number.")(fn)
        fn = click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")(fn)
        fn = click.option("--color", type=click.Choice(splatconv.COLOR_MODES), default="auto", show_default=True,
                          help="How to read PLY f_dc_0..2 (see convert).")(fn)
        return fn

    return decorate


def _finish(data: dict, as_json: bool, parts) -> None:
    from splatconv.report import to_json

    if as_json:
        click.echo(to_json(data))
    else:
        click.echo("\n\n".join(p(data) for p in parts))
    if not data["passed"]:
        raise SystemExit(1)


@main.command()
@click.argument("source", type=click.Path(dir_okay=False))
@click.argument("converted", type=click.Path(dir_okay=False))
@_view_options(times="0,0.25,0.5,0.75,1", cameras="all")
@click.option("--report-dir", type=click.Path(file_okay=False),
              help="Write each frame's images, a diff heatmap and a side-by-side picture here "
                   "(cam<I>_t<T>_{source,converted,diff,side_by_side}.png).")
@click.option("--force", is_flag=True, help="Replace files in --report-dir if they exist.")
@_library_errors
def verify(source, converted, size, cameras, times, min_psnr, as_json, color, report_dir, force):
    """Check that CONVERTED still shows what SOURCE does.

    Compares every attribute against what half-float and 8-bit quantization can
    explain, then draws SOURCE through the float reference path and CONVERTED as
    stored, from the same cameras (default: all) at the same times (default
    0,0.25,0.5,0.75,1), and compares the pixels. Exits 0 when every frame reaches
    --min-psnr and no attribute drifted, 1 otherwise. Existing --report-dir files
    are refused before anything is drawn unless --force.
    """
    from splatconv.render import camera as cam
    from splatconv.render.verify import DEFAULT_TIMES, parse_times, verify as run_verify
    from splatconv.report import frames_text, structure_text, verdict_text

    outcome = run_verify(source, converted, times=parse_times(times) if times else DEFAULT_TIMES,
                         cameras=cameras or "all", size=cam.parse_size(size) if size else None,
                         min_psnr=min_psnr, color=color, report_dir=report_dir, force=force)
    _finish(outcome.as_dict(), as_json, (structure_text, frames_text, verdict_text))


@main.command()
@click.argument("a", type=click.Path(dir_okay=False))
@click.argument("b", type=click.Path(dir_okay=False))
@_view_options(times="0.5", cameras="0")
@click.option("--out", type=click.Path(dir_okay=False), help="Write a heatmap of the (worst) difference here (.png).")
@click.option("--reference", is_flag=True, help="Draw scene files' attributes unquantized.")
@click.option("--force", is_flag=True, help="Replace --out if it exists.")
@_library_errors
def diff(a, b, size, cameras, times, min_psnr, as_json, color, out, reference, force):
    """Compare A and B: two images, or two scene files drawn the same way.

    Scene files are drawn at time 0.5 from camera 0 unless --times / --cameras
    say otherwise (one frame; verify draws five times from every camera). Prints
    PSNR, largest and mean error and the share of pixels off per frame (for two
    images, one row named by the files); exits 0 when every frame reaches
    --min-psnr, 1 otherwise.
    """
    from splatconv.render.commands import diff_files
    from splatconv.render.diff import images_text, images_verdict_text
    from splatconv.report import frames_text, verdict_text

    outcome = diff_files(a, b, size=size, cameras=cameras, times=times, min_psnr=min_psnr, color=color,
                         out=out, reference=reference, force=force)
    images = bool(outcome.frames) and bool(outcome.frames[0].names)
    parts = (images_text, images_verdict_text) if images else (frames_text, verdict_text)
    _finish(outcome.as_dict(), as_json, parts)


@main.command()
@click.argument("files", metavar="FILE...", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--port", type=click.IntRange(0, 65535), default=0, help="Port on 127.0.0.1 [default: a free one].")
@click.option("--no-open", is_flag=True, help="Do not open a browser; just print the address.")
@_library_errors
def view(files, port, no_open):
    """Play FILE in the browser: serves the player page and the scene on 127.0.0.1 only.

    Several FILEs play as the segments of one clip. A PLY or .zst input is
    converted in memory first. Stop with Ctrl-C.

    Example: splatconv view scene.splatv --no-open
    """
    from splatconv.web.server import ViewServer

    server = ViewServer(files, port=port)
    _notes(server.notes)
    click.echo(f"serving {', '.join(files)} at {server.url} (Ctrl-C to stop)")
    server.serve(open_browser=not no_open)


if __name__ == "__main__":  # pragma: no cover
    main()
