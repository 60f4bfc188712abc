"""Commands that make new scenes from scenes: ``bake`` (a moment as a static scene) and ``merge`` (compose)."""

from __future__ import annotations

import click

from .. import io
from ..formats import FRAME_SUFFIX, REGISTRY
from ..jobs.bake import bake as bake_job
from ..jobs.bake import bake_frames
from ..jobs.merge import merge as merge_job
from ..ops import make_transform
from ..ops.bake import MAX_FRAMES
from ..publish import PageOptions
from ..wording import plural
from ._base import (FINITE, Failure, color_option, force_option, library_errors, main, notes, options, page_options,
                    progress, quality_option, quiet_option, wrote)
from ._edit import FloatList, Rotation
from ._segments import given as segments_given
from ._segments import run as run_segments
from ._segments import segment_options


class Moment(click.ParamType):
    """A time the viewer shows: a finite number in [0, 1]."""

    name = "T"

    def convert(self, value, param, ctx):
        number = FINITE.convert(value, param, ctx)
        if not 0.0 <= number <= 1.0:
            self.fail(f"{value!r} is not in the viewer's time range [0, 1].", param, ctx)
        return number


class PerInput(click.ParamType):
    """``N:VALUE``: a value for input N (1 for the first), VALUE as ``inner`` reads it."""

    def __init__(self, inner: click.ParamType, metavar: str):
        self.inner = inner
        self.name = f"N:{metavar}"

    def get_metavar(self, param, ctx=None):
        return self.name

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        head, sep, rest = str(value).partition(":")
        if not sep or not head.strip().isdigit() or int(head) < 1:
            self.fail(f"{value!r}: expected {self.name}, N the input's number (1 for the first).", param, ctx)
        return int(head), self.inner.convert(rest, param, ctx)


#: Per-input transform options of ``merge``: option name -> parameter of :func:`make_transform`.
_PLACEMENT = ("translate", "rotate", "scale")


def _placements(count: int, values: dict) -> dict:
    """Input number (1-based) -> the :class:`~splatconv.ops.transform.Transform` its options give.

    Raises
    ------
    Failure
        (usage) for an input number past the inputs, or an option given twice for one input.
    """
    given = {}
    for option in _PLACEMENT:
        for index, value in values[option]:
            if index > count:
                raise Failure(f"--{option} {index}:...: there are {count} inputs (1..{count})", 2)
            if option in given.setdefault(index, {}):
                raise Failure(f"--{option} given twice for input {index}", 2)
            given[index][option] = value
    return {index: make_transform(**args) for index, args in given.items()}


def _drop_option(what: str):
    return click.option("--drop-nonfinite", is_flag=True,
                        help=f"Remove splats with a NaN or infinite position, rotation, motion, omega or trbf "
                             f"centre, or a NaN or +inf scale (as convert does) from {what} first.")


def _layout_option(default: str):
    return click.option("--layout", "--ply-layout", "layout", type=click.Choice(io.LAYOUTS),
                        help=f"PLY output: 3dgs (plain 3DGS, SH degree 0) or lite (Spacetime Gaussians); "
                             f"default: {default}. .glb/.gltf output: spz (SPZ-compressed, the draft "
                             f"KHR_gaussian_splatting_compression_spz_2; lossy).")


def _sort_option():
    return click.option("--sort", type=click.Choice(io.SORT_MODES),
                        help="Record order: importance (largest, most opaque first) or none (input order). "
                             "Default: the output format's (importance for .splat and .splatv, none for .ply).")


@main.command()
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.argument("output_path", metavar="OUTPUT", type=click.Path())
@options(
    click.option("--time", "time", type=Moment(),
                 help="The moment to bake, in the viewer's time [0, 1]. OUTPUT is a file."),
    click.option("--frames", type=click.IntRange(2, MAX_FRAMES), metavar="N",
                 help="Bake N moments, frame k at time k/(N-1), as OUTPUT/frame_0000.ply ... "
                      f"OUTPUT is a folder (made if missing); all frames are written or none. At most {MAX_FRAMES:,}."),
    click.option("--frame-suffix", type=click.Choice(sorted(REGISTRY)), default=FRAME_SUFFIX, show_default=True,
                 help="File type of the --frames files."),
    _layout_option("3dgs"),
    _sort_option(),
    quality_option(),
    color_option(),
    click.option("--drop-nonfinite", is_flag=True,
                 help="Also remove baked splats left with a NaN or infinite position, scale or colour, so that every "
                      "value written is finite (rotations and opacities always are; flat splats are kept)."),
    *page_options(),
    force_option("OUTPUT (or existing frame files)"),
    quiet_option(),
)
@library_errors
def bake(input_path, output_path, time, frames, frame_suffix, layout, sort, quality, color, drop_nonfinite, fit,
         no_poster, force, quiet):
    """Write the scene as the viewer shows it at one time, as a static scene.

    Positions and rotations at that time, opacity times the temporal opacity,
    no motion; only splats the viewer draws then are written (a note counts the
    others: zero rotation, NaN position, alpha zero, hidden in time: temporal
    opacity below 0.02). The result shows that moment at every time. OUTPUT is a 3DGS PLY
    (what 3DGS tools and web viewers open) or an antimatter15 .splat (or a
    .splatv); the format comes from its extension.

    \b
    Example:
      splatconv bake scene.splatv moment.ply --time 0.5
      splatconv bake scene.ply moment.splat --time 0.25
      splatconv bake scene.splatv flipbook/ --frames 30
    """
    if (time is None) == (frames is None):
        raise Failure("give either --time T (one moment) or --frames N (a folder of moments)", 2)
    page = PageOptions(fit=fit, poster=not no_poster)
    if frames is None:
        _report, written = bake_job(input_path, output_path, time=time, sort=sort, layout=layout, quality=quality,
                                    color=color, drop_nonfinite=drop_nonfinite, force=force, page=page,
                                    progress=progress(quiet), tell=notes)
        wrote(output_path, written)
        return
    page.check(output_path)
    names, moments, reports = bake_frames(input_path, output_path, frames=frames, suffix=frame_suffix, sort=sort,
                                          layout=layout, quality=quality, color=color,
                                          drop_nonfinite=drop_nonfinite, force=force, progress=progress(quiet),
                                          tell=notes)
    counts = [r.count for r in reports]
    click.echo(f"wrote {frames} frames to {output_path}: {names[0]} .. {names[-1]} (t = {moments[0]:g} .. "
               f"{moments[-1]:g}), {min(counts):,} to {plural(max(counts), 'splat')} a frame")


@main.command()
@click.argument("paths", metavar="INPUT... OUTPUT", nargs=-1, required=True, type=click.Path(dir_okay=False))
@options(
    click.option("--translate", type=PerInput(FloatList(3, "X,Y,Z"), "X,Y,Z"), multiple=True,
                 help="Move input N by (X, Y, Z), e.g. --translate 2:1.5,0,0. Repeat for other inputs."),
    click.option("--rotate", type=PerInput(Rotation(), "STEPS"), multiple=True,
                 help="Turn input N: steps AXIS:DEGREES (2:y:90 or 2:x:90,y:45; right-handed) or "
                      "2:quat:W,X,Y,Z."),
    click.option("--scale", type=PerInput(click.FloatRange(min=0, min_open=True), "S"), multiple=True,
                 help="Scale input N uniformly by S > 0 (1.2e-38 to 3.4e38), e.g. --scale 2:0.5."),
    _layout_option("3dgs when every input is plain 3DGS (a 3DGS PLY, a .splat, a baked moment), else lite"),
    _sort_option(),
    quality_option(),
    color_option(),
    _drop_option("every INPUT"),
    *segment_options(),
    *page_options(),
    force_option(),
    quiet_option(),
)
@library_errors
def merge(paths, translate, rotate, scale, layout, sort, quality, color, drop_nonfinite, fit, no_poster, force, quiet,
          segments, **segment):
    """Put several scenes in one file on the same timeline.

    A static 3DGS background under a dynamic actor, two actors side by side:
    every splat of every input is kept as it is, so each input looks at every
    time as it did alone (moved first by its own --translate, --rotate and
    --scale, N: naming the input, applied as p' = R(S p) + T with motion,
    rotations and scales). Static inputs (3DGS PLY, .splat) stay at full opacity
    over the whole clip. The output keeps the cameras of the first input that
    has any (moved with it).

    With --segments the inputs are laid end to end instead (Spacetime
    Gaussians segments of one long clip): segment i plays in its own interval
    of the timeline, its long-lived splats split into pieces that fade out at
    its ends, and a sample of output frames (every frame with --check-every 1)
    is measured against its segment alone (see docs/long-clips.md and
    specs/segments.md).

    \b
    Example:
      splatconv merge background.ply actor.splatv scene.splatv
      splatconv merge stage.ply dancer.splatv dancer.splatv duet.splatv --translate 2:-1,0,0 --translate 3:1,0,0
      splatconv merge seg0.ply seg1.ply seg2.ply clip.splatv --segments --durations 50,50,50
    """
    if len(paths) < 3:
        raise Failure("merge needs at least two INPUT files and an OUTPUT", 2)
    inputs, output_path = list(paths[:-1]), paths[-1]
    page = PageOptions(fit=fit, poster=not no_poster)
    if segments:
        if translate or rotate or scale or drop_nonfinite:
            raise Failure("--translate, --rotate, --scale and --drop-nonfinite apply to merges on one timeline, "
                          "not to --segments", 2)
        return run_segments(inputs, output_path, layout=layout, sort=sort, quality=quality, color=color,
                            force=force, quiet=quiet, page=page, **segment)
    if segments_given(segment):
        raise Failure("--durations, --leak, --budget, --check-every, --no-check, --camera and --json apply to "
                      "--segments only", 2)
    placements = _placements(len(inputs), {"translate": translate, "rotate": rotate, "scale": scale})
    _report, written = merge_job(inputs, output_path, placements=placements, sort=sort, layout=layout,
                                 quality=quality, color=color, drop_nonfinite=drop_nonfinite, force=force,
                                 page=page, progress=progress(quiet), tell=notes)
    wrote(output_path, written)
