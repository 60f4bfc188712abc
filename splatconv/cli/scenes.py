"""``convert``: scene files, frame sequences and player pages (``info`` and ``stats`` are in :mod:`.facts`)."""

from __future__ import annotations

import click

from .. import io
from ..jobs.frames import convert_frames, is_sequence
from ..jobs.prove import convert_proven
from ..ops.sequence import SAME_SPLATS_MODES
from ..publish import PageOptions, is_page, publish
from ..text import sequence_text
from ._base import (FINITE, POSITIVE, Failure, color_option, force_option, library_errors, main, notes, options,
                    page_options, progress, proof_options, quality_option, quiet_option, wrote, zstd_option)
from ._edit import edit_options, scene_editor


class _Times(click.ParamType):
    """A comma-separated list of finite numbers."""

    name = "T0,T1,..."

    def convert(self, value, param, ctx):
        if isinstance(value, list):
            return value
        return [FINITE.convert(part.strip(), param, ctx) for part in str(value).split(",")]


def sequence_options():
    return (
        click.option("--frame-times", type=_Times(), default=None,
                     help="Frame sequences: the time of each frame in the viewer's [0, 1], comma-separated, "
                          "increasing and distinct as the output stores times (halves in a .splatv) "
                          "(default: frame k of N at k/(N-1))."),
        click.option("--same-splats", type=click.Choice(SAME_SPLATS_MODES), default="auto", show_default=True,
                     help="Frame sequences: whether row i of every frame is the same splat (its motion is "
                          "fitted); auto: when every frame has the same count."),
        click.option("--max-error", type=POSITIVE, default=None,
                     help="Frame sequences: largest position error (scene units) of a fitted splat before it "
                          "is split into pieces (default: 0.001 of the first frame's extent)."),
    )


def _convert_frames(inputs, output_path, *, edits, quiet, **options):
    """``convert`` of a frame sequence: fit or stack the frames, then write."""
    if any(v not in (None, False, ()) for v in edits.values()):
        raise Failure("edit options apply to one INPUT, not to a frame sequence (convert it first)", 2)
    _scene, fit, report, _ = convert_frames(inputs, output_path, progress=progress(quiet), tell=notes, **options)
    click.echo(sequence_text(fit.as_dict()))
    wrote(output_path, report)


@main.command()
@click.argument("input_paths", metavar="INPUT...", nargs=-1, required=True, type=click.Path())
@click.argument("output_path", metavar="OUTPUT", type=click.Path(dir_okay=False))
@options(
    click.option("--external", is_flag=True,
                 help="For an .html OUTPUT: write the scene beside the page (OUT.splatv; OUT.splatvq for a "
                      ".splatvq INPUT or with --quality) instead of embedding it, for scenes too large to embed; "
                      "the page must then be served over HTTP."),
    click.option("--durations", metavar="D0,D1,...",
                 help="For several INPUTs to .html: each segment's share of the clip's timeline, e.g. its "
                      "frames [default: equal shares]."),
    click.option("--compat", type=click.Choice(io.COMPAT_MODES),
                 help="splatv-js: texture bytes identical to splaTV's in-browser converter "
                      "(truncating halves). Default: accurate rounding."),
    click.option("--sort", type=click.Choice(io.SORT_MODES),
                 help="Record order: importance (largest, most opaque first, so the viewer can draw "
                      "while streaming) or none (input order). Default: the output format's "
                      "(importance for .splatv, none for .ply)."),
    click.option("--cameras", "cameras", type=click.Path(dir_okay=False),
                 help="A 3DGS / Spacetime Gaussians cameras.json to store in the output."),
    click.option("--layout", "--ply-layout", "layout", type=click.Choice(io.LAYOUTS),
                 help="PLY output: lite (Spacetime Gaussians, keeps motion and time) or 3dgs (plain 3DGS, "
                      "SH degree 0; static scenes only). Default: 3dgs for a plain 3DGS input, else lite. "
                      ".glb/.gltf output: spz, the splats as one SPZ v2 stream (the draft "
                      "KHR_gaussian_splatting_compression_spz_2: several times smaller, lossy, noted; viewers "
                      "without it draw nothing). Default: float attributes."),
    quality_option(),
    *proof_options(),
    color_option(),
    zstd_option("a .zst OUTPUT, e.g. scene.splatv.zst"),
    *sequence_options(),
    *page_options(),
    force_option(),
    quiet_option(),
)
@edit_options()
@library_errors
def convert(input_paths, output_path, external, durations, compat, sort, cameras, layout, quality, min_psnr,
            max_bytes, best_effort, prune, no_proof, color, zstd_level, frame_times, same_splats, max_error, fit,
            no_poster, force, quiet, **edits):
    """Convert INPUT to OUTPUT; formats by extension (.ply, .splatv, .splatvq, .splat, .spz, .sog, .glb, ...;
    any + .zst; .html: a player page).

    Lossy steps (saturated halves, clamped colours, dropped properties) are
    reported as notes on stderr. OUTPUT is written atomically; a .zst OUTPUT is
    compressed while it is written. Several INPUTs make one .html page that
    plays them as the segments of one clip.

    \b
    Example:
      splatconv convert scene.ply scene.splatv --cameras cameras.json
      splatconv convert scene.splatv scene.ply
      splatconv convert 'frames/*.ply' clip.splatv --max-error 0.001
      splatconv convert scene.splatv scene.html
      splatconv convert scene.ply scene.splatvq
      splatconv convert scene.ply scene.splatvq --quality small --prune
      splatconv convert scene.ply scene.splatvq --max-bytes 5M
      splatconv convert scene.ply scene.glb --layout spz

    A .splatvq OUTPUT proves its quality: the file written is drawn against
    the scene it encodes and reaches its setting's floor (or --min-psnr), or
    the command fails; the note says what it reached.
    """
    page = PageOptions(fit=fit, poster=not no_poster)
    proving = min_psnr is not None or max_bytes is not None or best_effort or prune or no_proof
    # Player pages of several segments or with --external: splatconv.publish.
    if external or durations or (len(input_paths) > 1 and is_page(output_path)):
        # A page's segments are played as they are read, not fitted as frames: nothing else applies.
        if (compat or sort or cameras or layout or zstd_level or proving or scene_editor(edits) or color != "auto"
                or frame_times is not None or same_splats != "auto" or max_error is not None):
            raise Failure("--external and several inputs take no other options but --durations, --quality, "
                          "--fit, --no-poster and --force", 2)
        report = publish(input_paths, output_path, external=external, force=force, durations=durations,
                         quality=quality, fit=fit, poster=not no_poster)
        notes(report.notes)
        for path, size in report.written:
            click.echo(f"wrote {path}: {size:,} bytes")
        return
    if is_sequence(input_paths):
        if proving:
            raise Failure("--min-psnr, --max-bytes, --best-effort, --prune and --no-proof apply to one INPUT "
                          "(convert a frame sequence first)", 2)
        _convert_frames(input_paths, output_path, compat=compat, sort=sort, cameras=cameras, layout=layout,
                        quality=quality, color=color, zstd_level=zstd_level, frame_times=frame_times,
                        same_splats=same_splats, max_error=max_error, page=page, force=force, quiet=quiet,
                        edits=edits)
        return
    if frame_times is not None or same_splats != "auto" or max_error is not None:
        raise Failure("--frame-times, --same-splats and --max-error apply to frame sequences only", 2)
    input_path = input_paths[0]
    _scene, report = convert_proven(input_path, output_path, min_psnr=min_psnr, max_bytes=max_bytes,
                                    best_effort=best_effort, prune=prune, proof=not no_proof, compat=compat,
                                    sort=sort, cameras=cameras, color=color, force=force, zstd_level=zstd_level,
                                    layout=layout, quality=quality, progress=progress(quiet),
                                    edit=scene_editor(edits), page=page, tell=notes)
    wrote(output_path, report)

