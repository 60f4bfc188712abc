"""Commands that make new scenes from scenes: ``bake`` (a moment as a static scene) and ``merge`` (compose)."""

from __future__ import annotations

import os

import click

from .. import io
from ..formats import REGISTRY
from ..fsutil import check_output
from ..ops import bake as bake_ops
from ..ops import merge as merge_ops
from ._base import (FINITE, Failure, color_option, force_option, library_errors, main, notes, options, progress,
                    quiet_option)


class Moment(click.ParamType):
    """A time the viewer shows: a finite number in [0, 1]."""

    name = "T"

    def convert(self, value, param, ctx):
        number = FINITE.convert(value, param, ctx)
        if not 0.0 <= number <= 1.0:
            self.fail(f"{value!r} is not in the viewer's time range [0, 1].", param, ctx)
        return number


def _layout_option(default: str):
    return click.option("--ply-layout", "layout", type=click.Choice(io.LAYOUTS),
                        help=f"PLY output: 3dgs (plain 3DGS, SH degree 0) or lite (Spacetime Gaussians). "
                             f"Default: {default}.")


def _sort_option():
    return click.option("--sort", type=click.Choice(io.SORT_MODES),
                        help="Record order: importance (largest, most opaque first) or none (input order). "
                             "Default: the output format's (importance for .splat and .splatv, none for .ply).")


def _wrote(path, report) -> None:
    click.echo(f"wrote {path}: {report.count:,} splats, {os.path.getsize(path):,} bytes")


@main.command()
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.argument("output_path", metavar="OUTPUT", type=click.Path())
@options(
    click.option("--time", "time", type=Moment(),
                 help="The moment to bake, in the viewer's time [0, 1]. OUTPUT is a file."),
    click.option("--frames", type=click.IntRange(min=2), metavar="N",
                 help="Bake N moments, frame k at time k/(N-1), as OUTPUT/frame_0000.ply ... "
                      "OUTPUT is a folder (made if missing); all frames are written or none."),
    click.option("--frame-suffix", type=click.Choice(sorted(REGISTRY)), default=".ply", show_default=True,
                 help="File type of the --frames files."),
    _layout_option("3dgs"),
    _sort_option(),
    color_option(),
    force_option("OUTPUT (or existing frame files)"),
    quiet_option(),
)
@library_errors
def bake(input_path, output_path, time, frames, frame_suffix, layout, sort, color, force, quiet):
    """Write the scene as the viewer shows it at one time, as a static scene.

    Positions and rotations at that time, opacity times the temporal opacity,
    no motion; splats the viewer hides then (temporal opacity below 0.02) are
    removed. The result shows that moment at every time. OUTPUT is a 3DGS PLY
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
    if frames is None:
        io.check_write_options(output_path, sort=sort, layout=layout)
        check_output(output_path, [input_path], force)
        scene = io.read(input_path, color=color)
        notes(scene.notes)
        baked, report = bake_ops.bake(scene, time)
        notes(report.notes)
        written = io.write(baked, output_path, sort=sort, layout=layout, force=force, inputs=[input_path],
                           progress=progress(quiet))
        notes(written.notes)
        _wrote(output_path, written)
        return
    scene = io.read(input_path, color=color)
    notes(scene.notes)
    names = bake_ops.frame_names(frames, frame_suffix)
    moments = list(bake_ops.frame_times(frames))
    baked = (b for _t, b, _r in _report_each(bake_ops.bake_frames(scene, frames), names))
    reports = io.write_sequence(baked, output_path, names, sort=sort, layout=layout, force=force,
                                inputs=[input_path], progress=progress(quiet))
    for name, report in zip(names, reports):
        notes(f"{name}: {line}" for line in report.notes)
    counts = [r.count for r in reports]
    click.echo(f"wrote {frames} frames to {output_path}: {names[0]} .. {names[-1]} (t = {moments[0]:g} .. "
               f"{moments[-1]:g}), {min(counts):,} to {max(counts):,} splats a frame")


def _report_each(frames, names):
    """Pass baked frames on, echoing each one's notes as it is made."""
    for name, (t, baked, report) in zip(names, frames):
        notes(f"{name}: {line}" for line in report.notes)
        yield t, baked, report


@main.command()
@click.argument("paths", metavar="INPUT... OUTPUT", nargs=-1, required=True, type=click.Path(dir_okay=False))
@options(
    click.option("--mode", type=click.Choice(merge_ops.MODES), default="overlay", show_default=True,
                 help="overlay: all inputs together on the same timeline."),
    _layout_option("3dgs when every input is plain 3DGS (a 3DGS PLY, a .splat, a baked moment), else lite"),
    _sort_option(),
    color_option(),
    force_option(),
    quiet_option(),
)
@library_errors
def merge(paths, mode, layout, sort, color, force, quiet):
    """Put several scenes in one file on the same timeline.

    A static 3DGS background under a dynamic actor, two actors side by side:
    every splat of every input is kept as it is, so each input looks at every
    time as it did alone. Static inputs (3DGS PLY, .splat) stay at full opacity
    over the whole clip. The output keeps the cameras of the first input that
    has any.

    \b
    Example:
      splatconv merge background.ply actor.splatv scene.splatv
    """
    if len(paths) < 3:
        raise Failure("merge needs at least two INPUT files and an OUTPUT", 2)
    inputs, output_path = list(paths[:-1]), paths[-1]
    io.check_write_options(output_path, sort=sort, layout=layout)
    check_output(output_path, inputs, force)
    scenes = []
    for path in inputs:
        scene = io.read(path, color=color)
        notes(f"{path}: {line}" for line in scene.notes)
        scenes.append(scene)
    merged, report = merge_ops.overlay(scenes)
    notes(report.notes)
    written = io.write(merged, output_path, sort=sort, layout=layout, force=force, inputs=inputs,
                       progress=progress(quiet))
    notes(written.notes)
    _wrote(output_path, written)
