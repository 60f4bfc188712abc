"""The edit options of ``convert`` (filters, trim, transform) as one option stack, and what applies them."""

from __future__ import annotations

import math

import click

from ..errors import UnsupportedError, UsageError
from ..ops import ORDER, EditPlan, apply_edits, make_transform, parse_rotation
from ._base import options


class FloatList(click.ParamType):
    """Exactly ``count`` finite numbers separated by commas, e.g. ``1,2,3``."""

    def __init__(self, count: int, metavar: str):
        self.count = count
        self.name = metavar
        self.metavar = metavar

    def get_metavar(self, param, ctx=None):
        return self.metavar

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        parts = str(value).split(",")
        try:
            numbers = tuple(float(p) for p in parts)
        except ValueError:
            self.fail(f"{value!r}: expected {self.count} numbers separated by commas ({self.metavar}).", param, ctx)
        if len(numbers) != self.count:
            self.fail(f"{value!r}: expected {self.count} numbers separated by commas ({self.metavar}).", param, ctx)
        if not all(math.isfinite(v) for v in numbers):
            self.fail(f"{value!r}: every number must be finite.", param, ctx)
        return numbers


class Rotation(click.ParamType):
    """A ``--rotate`` value, checked when parsed (kept as text)."""

    name = "STEPS"

    def convert(self, value, param, ctx):
        try:
            parse_rotation(value)
        except UsageError as e:
            self.fail(str(e).removeprefix("--rotate: "), param, ctx)
        return value


class Fraction(click.ParamType):
    """A finite number in [0, 1]."""

    name = "A"

    def convert(self, value, param, ctx):
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number.", param, ctx)
        if not 0.0 <= number <= 1.0:  # NaN fails too
            self.fail(f"{value!r} is not in [0, 1].", param, ctx)
        return number


_POSITIVE_SCALE = click.FloatRange(min=0, min_open=True)

#: Option names of the edits, in :data:`splatconv.ops.ORDER`.
EDIT_KEYS = ("drop_undrawable", "drop_nonfinite", "trim", "crop", "min_opacity", "max_splats", "translate", "rotate",
             "scale")


#: The edit example added to the command's Example block.
EXAMPLE = "splatconv convert scene.ply clean.splatv --drop-nonfinite --trim 0.25,0.75 --rotate x:180"


def edit_options():
    """The edit options as one stack; also adds the order they apply in to the command's help."""
    stack = options(
        click.option("--drop-undrawable", is_flag=True,
                     help="Remove splats the viewer can never draw at any time in [0, 1] (zero rotation and "
                          "omega, NaN position or motion, alpha byte 0, below the temporal cut throughout); "
                          "says how many of each kind."),
        click.option("--drop-nonfinite", is_flag=True,
                     help="Remove splats with a NaN or infinite position, rotation, motion, omega or trbf "
                          "centre, a NaN or +inf scale, a NaN or -inf trbf scale, or a NaN opacity or colour "
                          "(a zero scale, -inf: a flat splat, and +inf trbf scale, 'visible at every time', "
                          "are kept)."),
        click.option("--trim", type=FloatList(2, "T0,T1"),
                     help="Keep what is visible somewhere in [T0, T1] (0 <= T0 < T1 <= 1) and stretch that "
                          "interval onto the clip's [0, 1]."),
        click.option("--crop", type=FloatList(6, "X0,Y0,Z0,X1,Y1,Z1"),
                     help="Keep splats whose centre at their time of peak opacity (trbf centre within the clip) "
                          "lies in this box, in the input's coordinates."),
        click.option("--min-opacity", type=Fraction(),
                     help="Remove splats whose peak opacity sigmoid(opacity) is below A."),
        click.option("--max-splats", type=click.IntRange(min=0), metavar="N",
                     help="Keep the N most important splats (the writer's importance order: size x opacity)."),
        click.option("--translate", type=FloatList(3, "X,Y,Z"), help="Move the scene by (X, Y, Z)."),
        click.option("--rotate", type=Rotation(),
                     help="Turn the scene: steps AXIS:DEGREES applied left to right (x:90,y:45; right-handed, "
                          "x:90 takes +y to +z) or quat:W,X,Y,Z."),
        click.option("--scale", type=_POSITIVE_SCALE, metavar="S",
                     help="Scale the scene uniformly by S > 0 (float32's smallest normal, 1.2e-38, to its largest "
                          "number, 3.4e38)."),
    )

    def apply(fn):
        doc = (fn.__doc__ or "").rstrip()
        order = ", ".join(f"--{name}" for name in ORDER[:-1]) + ", then --translate/--rotate/--scale"
        paragraph = (f"Edits apply in this order, whatever the order of the options: {order}, "
                     "as p' = R(S p) + T (motion, rotations, scales and stored cameras move with the "
                     "scene). Each says on stderr what it removed or changed.\n\n    ")
        at = doc.find("\b\n    Example:")
        if at >= 0:
            # Add an edit example at the end of the Example block (a paragraph may follow it).
            end = doc.find("\n\n", at)
            end = len(doc) if end < 0 else end
            doc = doc[:at] + paragraph + doc[at:end] + f"\n      {EXAMPLE}" + doc[end:]
        else:
            doc += "\n\n    " + paragraph
        fn.__doc__ = doc + "\n    "
        return stack(fn)

    return apply


def plan_of(values: dict) -> EditPlan | None:
    """The :class:`~splatconv.ops.EditPlan` of the edit options' values; None when none is given.

    Raises
    ------
    UsageError
        For values the library refuses (an empty box, an interval outside [0, 1], ...).
    """
    v = {key: values.get(key) for key in EDIT_KEYS}
    transform = None
    if v["translate"] is not None or v["rotate"] is not None or v["scale"] is not None:
        transform = make_transform(v["translate"], v["rotate"], v["scale"])
    crop = None if v["crop"] is None else (v["crop"][:3], v["crop"][3:])
    plan = EditPlan(drop_undrawable=bool(v["drop_undrawable"]), drop_nonfinite=bool(v["drop_nonfinite"]),
                    trim=v["trim"], crop=crop, min_opacity=v["min_opacity"], max_splats=v["max_splats"],
                    transform=transform)
    return None if plan.empty else plan


def scene_editor(values: dict):
    """What ``convert`` applies between reading and writing, from the edit options; None for no edits.

    The callable takes a scene and returns the edited one, whose ``notes`` end
    with what each edit removed or changed. It refuses to hand on a scene the
    edits emptied (writing nothing is never what was meant).
    """
    plan = plan_of(values)
    if plan is None:
        return None

    def edit(scene):
        edited, reports = apply_edits(scene, plan)
        if edited.count == 0 and scene.count:
            removed = "; ".join(f"{r.op} removed {r.removed:,}" for r in reports if r.removed)
            raise UnsupportedError(f"the edits leave no splats ({removed}); nothing written")
        return edited

    return edit
