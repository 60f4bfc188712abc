"""``merge --segments``: segment files end to end on one timeline, with a per-frame fidelity report."""

from __future__ import annotations

import click

from ..jobs.segments import merge_segments, segments_findings
from ..ops.segments import DEFAULT_BUDGET, DEFAULT_FRAMES, DEFAULT_LEAK, MAX_FRAMES
from ..render.fidelity import DEFAULT_CAMERA, DEFAULT_SAMPLE, SAMPLE_HAND_OVERS
from ..text import segments_text, to_json
from ..wording import plural
from ._base import Failure, notes, progress


class _Counts(click.ParamType):
    """A comma-separated list of whole numbers >= 2."""

    name = "N0,N1,..."

    def convert(self, value, param, ctx):
        if isinstance(value, list):
            return value
        try:
            counts = [int(part) for part in str(value).split(",")]
        except ValueError:
            self.fail(f"{value!r} is not a comma-separated list of frame counts.", param, ctx)
        if any(c < 2 for c in counts):
            self.fail(f"{value!r}: every segment needs at least 2 frames.", param, ctx)
        return counts


def segment_options():
    """The options ``merge`` takes for ``--segments``, in help order."""
    return (
        click.option("--segments", is_flag=True,
                     help="Lay the inputs end to end (segment i in its own interval of [0, 1]) instead of together."),
        click.option("--durations", type=_Counts(), default=None,
                     help=f"--segments: frames of each segment, comma-separated; segment i gets that share of "
                          f"the timeline and its frames stay at frame times; at most {MAX_FRAMES:,} frames in all "
                          f"[default: {DEFAULT_FRAMES} each]."),
        click.option("--leak", type=click.IntRange(min=0), default=DEFAULT_LEAK, show_default=True,
                     help="--segments: frames of the next (previous) segment through which a segment's "
                          "long-lived splats fade out (in)."),
        click.option("--budget", type=click.FloatRange(min=1.0), default=DEFAULT_BUDGET, show_default=True,
                     help="--segments: at most this many times the segments' splats."),
        click.option("--check-every", type=click.IntRange(min=1), default=None, metavar="K",
                     help=f"--segments: measure every K-th output frame against its segment (1: every frame) "
                          f"instead of the default sample. Each frame checked costs two renders: every frame can "
                          f"take several times as long as the merge (docs/long-clips.md) "
                          f"[default: a sample: {DEFAULT_SAMPLE} frames spread evenly and both sides of the "
                          f"hand-overs between segments, at most {SAMPLE_HAND_OVERS} of them]"),
        click.option("--no-check", is_flag=True, help="--segments: skip the fidelity measurement."),
        click.option("--camera", type=click.IntRange(min=0), default=DEFAULT_CAMERA, show_default=True,
                     help="--segments: stored camera the fidelity is measured from."),
        click.option("--json", "as_json", is_flag=True,
                     help="--segments: print the report as JSON (keys in specs/json.md)."),
    )


def given(options: dict) -> bool:
    """Whether any --segments-only option differs from its default."""
    return (options["durations"] is not None or options["leak"] != DEFAULT_LEAK or options["budget"] != DEFAULT_BUDGET
            or options["check_every"] is not None or options["no_check"] or options["camera"] != DEFAULT_CAMERA
            or options["as_json"])


def run(inputs, output_path, *, layout, sort, quality, color, force, quiet, durations, leak, budget, check_every,
        no_check, camera, as_json, page=None) -> None:
    """The body of ``merge --segments``."""
    if durations is not None and len(durations) != len(inputs):
        raise Failure(f"--durations gives {plural(len(durations), 'value')} for {plural(len(inputs), 'segment')}", 2)
    if no_check and check_every is not None:
        raise Failure("--check-every and --no-check exclude each other", 2)
    _merged, report, written, checked = merge_segments(
        inputs, output_path, durations=durations, leak=leak, budget=budget, sort=sort, layout=layout,
        quality=quality, color=color, force=force, check=not no_check, check_every=check_every, camera=camera,
        page=page, progress=progress(quiet), tell=notes)
    data = segments_findings(report, written, output_path, checked)
    click.echo(to_json(data) if as_json else segments_text(data))
