"""Commands that draw: ``render``, ``verify``, ``diff`` (moderngl is imported only when they run)."""

from __future__ import annotations

import click

from ..render.camera import MAX_DEFAULT_WIDTH
from ..render.commands import DEFAULT_TIME, MAX_FRAMES, diff_files, render_file
from ..render.verify import DEFAULT_CAMERAS, DEFAULT_MIN_PSNR, DEFAULT_TIMES, DIFF_TIMES, VERIFY_MAX_WIDTH
from ..render.verify import verify as run_verify
from ..render.video import DEFAULT_FPS
from ..text import attributes_text, frames_text, images_text, images_verdict_text, to_json, verdict_text
from ._base import (FINITE, POSITIVE, Failure, color_option, force_option, library_errors, main, notes, options,
                    progress, quiet_option)


def _times_text(times) -> str:
    return ",".join(f"{t:g}" for t in times)


def _view_options(times, cameras: str):
    """Camera, time and size options shared by verify and diff, with each command's defaults."""
    return options(
        click.option("--times", default=None, help=f"Comma-separated scene times [default: {_times_text(times)}]."),
        click.option("--cameras", "cameras", default=None,
                     help=f"Cameras to draw from: 'all' or indices like 0,2 [default: {cameras}]."),
        click.option("--size", help=f"Image size WxH (default: each camera's, scaled down to at most "
                                    f"{VERIFY_MAX_WIDTH} wide). fx and fy scale with the size (unlike render: "
                                    "these compare what the camera saw)."),
        click.option("--min-psnr", type=FINITE, default=DEFAULT_MIN_PSNR, show_default=True,
                     help="Every frame must reach this PSNR (dB) to pass; a finite number."),
        click.option("--json", "as_json", is_flag=True, help="Print the result as JSON (specs/json.md)."),
        color_option(),
    )


def _finish(data: dict, as_json: bool, parts) -> None:
    notes(data["notes"])
    if as_json:
        click.echo(to_json(data))
    else:
        click.echo("\n\n".join(p(data) for p in parts))
    if not data["passed"]:
        raise SystemExit(1)


@main.command()
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.argument("output_path", metavar="OUTPUT", type=click.Path(dir_okay=False))
@options(
    click.option("--time", "time_", type=FINITE, default=DEFAULT_TIME, show_default=True,
                 help="Scene time of the frame (the viewer plays 0..1)."),
    click.option("--camera", type=int, help="Header camera to view from (default 0)."),
    click.option("--view", help="Column-major view matrix as the viewer keeps it in its URL hash: "
                                "a JSON list of 16 numbers."),
    click.option("--size", help=f"Image size WxH (of each frame). Default: the camera's, scaled down to at most "
                                f"{MAX_DEFAULT_WIDTH} wide, fx and fy scaled along. An explicit size keeps the "
                                "camera's fx and fy, as the viewer does in a window of that size (see --fit)."),
    click.option("--fit", is_flag=True,
                 help="Scale the camera's fx and fy with --size, by the smaller of the two size ratios, so the "
                      "camera's whole view shows (with bands along one side when the aspect ratios differ) "
                      "instead of the centre at the camera's focal length. Not with --fx or --fy."),
    click.option("--fx", type=POSITIVE, help="Focal length in pixels (default: the camera's; scaled with the "
                                             "default size)."),
    click.option("--fy", type=POSITIVE, help="Focal length in pixels (default: the camera's; scaled with the "
                                             "default size)."),
    click.option("--frames", type=click.IntRange(1, MAX_FRAMES), default=1, show_default=True,
                 help="Sweep N times over [0, 1], frame k at t = k/(N-1): an animated .gif or .webp, a video "
                      "(.mp4: H.264, .webm: VP9), or a labelled contact sheet for .png."),
    click.option("--fps", type=POSITIVE, help=f"Frames a second of an animation or video [default: "
                                              f"{DEFAULT_FPS:g} for a video, 10 for .gif and .webp]."),
    click.option("--orbit", type=FINITE, metavar="DEGREES",
                 help="Turn the camera (--camera, default 0) by DEGREES over the sweep, about its own up axis "
                      "through the scene's centre (the middle of the drawable splats' 2nd..98th percentile box)."),
    click.option("--path", "camera_path", metavar="A,B",
                 help="Move from header camera A to camera B over the sweep: position in a straight line, "
                      "rotation at a steady rate, in A's frame size. Not with --camera."),
    click.option("--reference", is_flag=True,
                 help="Draw a PLY's attributes unquantized (float reference path) instead of as the "
                      ".splatv texture the viewer would get."),
    color_option(),
    force_option(),
    quiet_option(),
)
@library_errors
def render(input_path, output_path, time_, camera, view, size, fit, fx, fy, frames, fps, orbit, camera_path,
           reference, color, force, quiet):
    """Render INPUT (.splatv or PLY) headlessly with the viewer's shader to OUTPUT.

    OUTPUT is a .png for one frame; with --frames N it is an animated .gif or
    .webp, a .mp4 or .webm video, or a .png contact sheet. The picture is the
    viewer's framebuffer: premultiplied colour over black. A video is encoded a
    frame at a time (needs PyAV: pip install 'splatconv[video]'); its width and
    height must be even (a camera's odd size is rounded down, an odd --size refused).

    \b
    Example:
      splatconv render scene.splatv frame.png --time 0.25 --camera 1
      splatconv render scene.splatv clip.gif --frames 24 --size 480x270
      splatconv render scene.splatv sheet.png --frames 9 --size 320x180 --fit
      splatconv render scene.splatv orbit.mp4 --frames 48 --size 640x360 --orbit 90
    """
    if camera is not None and view is not None:
        raise Failure("--camera and --view cannot be used together", 2)
    result = render_file(input_path, output_path, time=time_, camera=camera, view=view, size=size,
                         fx=fx, fy=fy, fit=fit, frames=frames, fps=fps, orbit=orbit, path=camera_path,
                         reference=reference, color=color, force=force, progress=progress(quiet))
    click.echo(result)


@main.command()
@click.argument("source", type=click.Path(dir_okay=False))
@click.argument("converted", type=click.Path(dir_okay=False))
@_view_options(DEFAULT_TIMES, f"the first {DEFAULT_CAMERAS}")
@options(
    click.option("--report-dir", type=click.Path(file_okay=False),
                 help="Write each frame's images, a diff heatmap and a side-by-side picture here "
                      "(cam<I>_t<T>_{source,converted,diff,side_by_side}.png)."),
    force_option("files in --report-dir"),
    click.option("--proof", is_flag=True,
                 help="Draw the views and times convert --min-psnr proves a .splatvq by (the header cameras, "
                      "views near them, splaTV's opening view; both files as the viewer draws them): its worst "
                      "frame is the one convert printed. Not with --times, --cameras or --size."),
    quiet_option(),
)
@library_errors
def verify(source, converted, times, cameras, size, min_psnr, as_json, color, report_dir, force, proof, quiet):
    """Check that CONVERTED still shows what SOURCE does.

    Compares every attribute against what half-float and 8-bit quantization can
    explain, then draws SOURCE through the float reference path and CONVERTED as
    stored, from the same cameras at the same times, and compares the pixels.
    By default it draws from the first few cameras only (a note says so when
    the file has more).
    Exits 0 when every frame reaches --min-psnr and no attribute drifted, 1
    otherwise. Existing --report-dir files are refused before anything is drawn
    unless --force.

    \b
    Example:
      splatconv verify scene.ply scene.splatv
      splatconv verify scene.ply scene.splatv --times 0,0.5,1 --cameras 0 --report-dir report/
    """
    outcome = run_verify(source, converted, times=times, cameras=cameras, size=size, min_psnr=min_psnr,
                         color=color, report_dir=report_dir, force=force, proof=proof, progress=progress(quiet))
    _finish(outcome.as_dict(), as_json, (attributes_text, frames_text, verdict_text))


@main.command()
@click.argument("a", type=click.Path(dir_okay=False))
@click.argument("b", type=click.Path(dir_okay=False))
@_view_options(DIFF_TIMES, "0")
@options(
    click.option("--out", type=click.Path(dir_okay=False),
                 help="Write a heatmap of the (worst) difference here (.png)."),
    click.option("--reference", is_flag=True, help="Draw scene files' attributes unquantized."),
    force_option("--out"),
    quiet_option(),
)
@library_errors
def diff(a, b, times, cameras, size, min_psnr, as_json, color, out, reference, force, quiet):
    """Compare A and B: two images, or two scene files drawn the same way.

    Scene files are drawn at one time from one camera unless --times / --cameras
    say otherwise (verify draws five times from several cameras). Prints PSNR,
    largest and mean error and the share of pixels off per frame (for two
    images, one row named by the files); exits 0 when every frame reaches
    --min-psnr, 1 otherwise.

    \b
    Example:
      splatconv diff a.png b.png --out heat.png
      splatconv diff scene.ply edited.splatv --times 0,1 --cameras all
    """
    outcome = diff_files(a, b, size=size, cameras=cameras, times=times, min_psnr=min_psnr, color=color,
                         out=out, reference=reference, force=force, progress=progress(quiet))
    images = bool(outcome.frames) and bool(outcome.frames[0].names)
    parts = (images_text, images_verdict_text) if images else (frames_text, verdict_text)
    _finish(outcome.as_dict(), as_json, parts)
