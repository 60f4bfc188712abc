"""Motion-aware rigid transforms with uniform scale: p' = R (S p) + T at every time.

For the viewer's splat at time t (see :mod:`splatconv.viewer`)::

    position(t) = xyz + m1 dt + m2 dt^2 + m3 dt^3
    rotation(t) = normalize(rot + omega dt)
    covariance  = R(rotation) diag(exp(scale))^2 R(rotation)^T

the transformed splat must sit at R S position(t) + T with covariance
S^2 R cov R^T at every t. That holds, for every t, when

* xyz -> R S xyz + T and each motion vector m_k -> R S m_k (the map is affine,
  so it passes through the polynomial term by term);
* rot -> q (x) rot and omega -> q (x) omega, the Hamilton product on the left by
  the rotation's unit quaternion q: q (x) (rot + omega dt) is then the new
  rot + omega dt, left multiplication by a unit quaternion keeps norms, so the
  viewer's normalisation commutes with it, and R(q (x) r) = R(q) R(r);
* log scales -> log scales + log S.

Time, opacity and the degree-0 colour do not change. SH bands of degrees 1 to 3, when the scene
holds them, turn with it: each degree's coefficients by the real Wigner D matrix of R
(:func:`splatconv.sh.rotation_matrix`), so the colour seen along R d is the one seen along d before. Cameras (``cameras.json`` form:
centre ``position``, camera-to-world ``rotation``) move with the scene: centre
-> R S c + T, rotation -> R rotation, so each camera sees the same image (its
camera-space coordinates are all multiplied by S, which a perspective
projection does not see; only depth-dependent effects such as the near and
far planes do).

Quaternions are (w, x, y, z), the model's rot_0..3 (the shader's rotation
matrix reads rot_0 as the real part).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from .. import sh
from ..errors import UnsupportedError, UsageError
from ..model import MOTION, OMEGA, POSITION, ROTATION, SCALE, SH_COEFFS, Scene, sh_degree, sh_names
from ..wording import plural
from ._table import copy_rows, derive, run_blocks, store_fields
from .report import OpReport

_AXES = {"x": 0, "y": 1, "z": 2}
#: float32's smallest normal number: the least --scale taken.
_FLOAT32_TINY = float(np.finfo(np.float32).tiny)
#: float32's largest number: the largest --scale and --translate taken.
_FLOAT32_MAX = float(np.finfo(np.float32).max)


def quaternion_matrix(q) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z): ``(3, 3) float64`` (rotates column vectors)."""
    w, x, y, z = (float(v) for v in q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def left_product_matrix(q) -> np.ndarray:
    """The ``(4, 4) float64`` matrix L with L @ r = q (x) r (Hamilton product, (w, x, y, z) order)."""
    w, x, y, z = (float(v) for v in q)
    return np.array([
        [w, -x, -y, -z],
        [x, w, -z, y],
        [y, z, w, -x],
        [z, -y, x, w],
    ])


def _cos_sin(degrees: float) -> tuple:
    """cos and sin of an angle in degrees, exact at multiples of 90 (so x:90 maps axes onto axes exactly)."""
    quarter = degrees / 90.0
    if quarter == int(quarter):
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(quarter) % 4]
    r = math.radians(degrees)
    return math.cos(r), math.sin(r)


def axis_rotation(axis: str, degrees: float) -> tuple:
    """Right-handed rotation by ``degrees`` about ``axis`` ("x", "y" or "z").

    Returns
    -------
    quaternion : (4,) float64 ndarray
        (w, x, y, z), unit.
    matrix : (3, 3) float64 ndarray
        Exact at multiples of 90 degrees (entries 0, 1, -1).
    """
    i = _AXES[axis]
    c, s = _cos_sin(degrees)
    j, k = (i + 1) % 3, (i + 2) % 3
    matrix = np.eye(3)
    matrix[j, j] = matrix[k, k] = c
    matrix[k, j], matrix[j, k] = s, -s
    hc, hs = _cos_sin(degrees / 2.0)
    quaternion = np.zeros(4)
    quaternion[0] = hc
    quaternion[1 + i] = hs
    return quaternion, matrix


@dataclass(frozen=True)
class Transform:
    """p' = R (S p) + T: a uniform scale, then a rotation, then a translation.

    Attributes
    ----------
    scale : float
        S > 0.
    rotation : (4,) tuple of float
        Unit quaternion (w, x, y, z) of R.
    translation : (3,) tuple of float
        T.
    matrix : (3, 3) tuple of tuple of float
        R as a matrix (given by :func:`parse_rotation` exactly at multiples of 90
        degrees; otherwise computed from ``rotation``).
    label : str
        How the rotation was given, for reports.
    """

    scale: float = 1.0
    rotation: tuple = (1.0, 0.0, 0.0, 0.0)
    translation: tuple = (0.0, 0.0, 0.0)
    matrix: tuple = field(default=None)
    label: str = ""

    def __post_init__(self):
        s = float(self.scale)
        if not (math.isfinite(s) and s > 0):
            raise UsageError(f"--scale: expected a finite number > 0, got {self.scale!r}")
        if s < _FLOAT32_TINY:
            # Positions are float32: scaled by a factor this small, every one would be
            # subnormal or 0 (1e-320 collapsed a scene to a point without a word).
            raise UsageError(f"--scale: {s:.3g} is below float32's smallest normal number ({_FLOAT32_TINY:.3g}): "
                             "positions would collapse to 0")
        if s > _FLOAT32_MAX:
            # Scaled by more, every position but 0 outgrows float32 (1e308 made them all infinite).
            raise UsageError(f"--scale: {s:.3g} is above float32's largest number ({_FLOAT32_MAX:.3g}): "
                             "positions would overflow to infinity")
        q = np.asarray(self.rotation, dtype=np.float64)
        norm = float(np.sqrt(q @ q)) if q.shape == (4,) else 0.0
        if not (math.isfinite(norm) and norm > 0):
            raise UsageError("--rotate: a rotation quaternion needs four finite numbers, not all zero")
        t = np.asarray(self.translation, dtype=np.float64)
        if t.shape != (3,) or not np.isfinite(t).all():
            raise UsageError("--translate: expected three finite numbers X,Y,Z")
        if (np.abs(t) > _FLOAT32_MAX).any():
            raise UsageError(f"--translate: {float(t[np.argmax(np.abs(t))]):.3g} is past float32's largest number "
                             f"({_FLOAT32_MAX:.3g}): positions would overflow to infinity")
        q = q / norm
        object.__setattr__(self, "scale", s)
        object.__setattr__(self, "rotation", tuple(float(v) for v in q))
        object.__setattr__(self, "translation", tuple(float(v) for v in t))
        m = quaternion_matrix(q) if self.matrix is None else np.asarray(self.matrix, dtype=np.float64)
        object.__setattr__(self, "matrix", tuple(tuple(float(v) for v in row) for row in m))

    @property
    def is_identity(self) -> bool:
        """Whether the transform changes nothing."""
        return (self.scale == 1.0 and self.translation == (0.0, 0.0, 0.0)
                and np.array_equal(np.asarray(self.matrix), np.eye(3)))

    def linear(self) -> np.ndarray:
        """R S as a ``(3, 3) float64`` matrix."""
        return np.asarray(self.matrix) * self.scale

    def apply_points(self, points) -> np.ndarray:
        """R (S p) + T for ``(M, 3)`` points: ``(M, 3) float64``."""
        p = np.asarray(points, dtype=np.float64)
        with np.errstate(over="ignore", invalid="ignore"):
            return p @ self.linear().T + np.asarray(self.translation)

    def describe(self) -> str:
        """The transform in words, e.g. ``S = 2, R = x:90, T = (1, 0, 0)``."""
        parts = []
        if self.scale != 1.0:
            parts.append(f"S = {self.scale:g}")
        if not np.array_equal(np.asarray(self.matrix), np.eye(3)):
            q = ", ".join(f"{v:.6g}" for v in self.rotation)
            parts.append(f"R = {self.label} (quaternion w,x,y,z {q})" if self.label else f"R = quaternion {q}")
        if self.translation != (0.0, 0.0, 0.0):
            parts.append(f"T = ({', '.join(f'{v:g}' for v in self.translation)})")
        return ", ".join(parts) or "identity"


def compose_rotation(steps) -> tuple:
    """Rotations applied one after another, first step first.

    Parameters
    ----------
    steps : iterable of (quaternion, matrix)

    Returns
    -------
    quaternion : (4,) float64 ndarray
    matrix : (3, 3) float64 ndarray
    """
    q = np.array([1.0, 0.0, 0.0, 0.0])
    m = np.eye(3)
    for sq, sm in steps:
        q = left_product_matrix(sq) @ q
        m = np.asarray(sm) @ m
    return q, m


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_STEP = re.compile(rf"\s*(?:([xyzXYZ])\s*:\s*({_NUMBER})|quat\s*:\s*({_NUMBER})\s*,\s*({_NUMBER})\s*,\s*"
                   rf"({_NUMBER})\s*,\s*({_NUMBER}))\s*(?:,|$)")


def parse_rotation(text: str) -> tuple:
    """A ``--rotate`` value: steps ``AXIS:DEGREES`` and ``quat:W,X,Y,Z``, comma-separated.

    Steps apply left to right: ``x:90,y:45`` turns 90 degrees about x, then 45
    about y (R = R_y R_x). Angles are right-handed: ``x:90`` takes (0, 1, 0) to
    (0, 0, 1). A quaternion step is normalised.

    Returns
    -------
    quaternion : (4,) float64 ndarray
        Unit (w, x, y, z).
    matrix : (3, 3) float64 ndarray

    Raises
    ------
    UsageError
        When the text is not a list of such steps, a number is not finite, or a
        quaternion is zero.
    """
    steps, pos = [], 0
    text = text.strip()
    if not text:
        raise UsageError("--rotate: expected steps such as x:90,y:-45 or quat:W,X,Y,Z")
    while pos < len(text):
        match = _STEP.match(text, pos)
        if match is None:
            raise UsageError(f"--rotate: cannot read {text[pos:]!r}; expected steps such as x:90,y:-45 "
                             f"or quat:W,X,Y,Z")
        axis, degrees, *quat = match.groups()
        if axis is not None:
            degrees = float(degrees)
            if not math.isfinite(degrees):
                raise UsageError(f"--rotate: {axis}:{match.group(2)} is not a finite angle")
            steps.append(axis_rotation(axis.lower(), degrees))
        else:
            q = np.array([float(v) for v in quat])
            norm = float(np.sqrt(q @ q))
            if not (np.isfinite(q).all() and math.isfinite(norm) and norm > 0):
                raise UsageError("--rotate: quat:W,X,Y,Z needs four finite numbers, not all zero")
            q = q / norm
            steps.append((q, quaternion_matrix(q)))
        pos = match.end()
        if text.endswith(",") and pos >= len(text):
            raise UsageError("--rotate: trailing comma")
    return compose_rotation(steps)


def make_transform(translate=None, rotate: str | None = None, scale: float | None = None) -> Transform:
    """The :class:`Transform` of the command-line options, whatever order they came in.

    Parameters
    ----------
    translate : sequence of 3 float, optional
    rotate : str, optional
        As :func:`parse_rotation` reads it.
    scale : float, optional
    """
    q, m = parse_rotation(rotate) if rotate else (np.array([1.0, 0, 0, 0]), np.eye(3))
    return Transform(scale=1.0 if scale is None else scale, rotation=tuple(q),
                     translation=tuple(translate) if translate is not None else (0.0, 0.0, 0.0),
                     matrix=m, label=(rotate or "").replace(" ", ""))


def _combine(terms, add: float, acc: np.ndarray, tmp: np.ndarray) -> np.ndarray:
    """sum of value * coefficient over ``terms`` (+ ``add`` to the first row of ``acc``), float64."""
    np.multiply(terms[0][0], terms[0][1], out=acc)
    for value, c in terms[1:]:
        np.multiply(value, c, out=tmp)
        acc += tmp
    if add:  # (not + 0.0: that would turn -0.0 into 0.0)
        acc[0] += add
    return acc


def _affine_group(block: dict, vectors, matrix: np.ndarray, offset=None) -> int:
    """Replace each vector of ``vectors`` by ``matrix @ v`` (the first one by ``matrix @ v + offset``), in float64.

    ``vectors`` are tuples of column names, all as long as ``matrix`` is wide
    (positions and the three motion vectors share one matrix, as do rotations
    and omega). Component i of every vector is computed at once, term by term
    on ``(vectors, k)`` float64 planes: numpy's matmul on (k, 3) @ (3, 3) goes
    through BLAS, whose thread start-up costs more than the arithmetic at this
    size. Zero coefficients are left out (x:90 keeps x exactly, whatever y and z
    hold), and every value gets the same float64 operations, in the same order,
    as it would alone. Runs under ``np.errstate(over="raise")`` (see
    :func:`block_transformer`): a value that outgrows float32 (or float64)
    raises, and only then is the component redone and the values that became
    infinite counted.

    Returns
    -------
    int
        Finite values that became infinite.
    """
    width, count, k = len(matrix), len(vectors), len(block[vectors[0][0]])
    planes = np.empty((width, count, k))  # planes[j, v]: component j of vector v
    for v, names in enumerate(vectors):
        for j, name in enumerate(names):
            planes[j, v] = block[name]
    out = np.empty((count, width, k), dtype=np.float32)  # out[v, i]: new component i of vector v
    acc, tmp = np.empty((count, k)), np.empty((count, k))
    grown = 0
    for i in range(width):
        terms = [(planes[j], c) for j, c in enumerate(matrix[i]) if c != 0.0]
        add = 0.0 if offset is None else float(offset[i])
        try:
            out[:, i] = _combine(terms, add, acc, tmp)
        except FloatingPointError:
            with np.errstate(over="ignore"):
                out[:, i] = _combine(terms, add, acc, tmp)
            finite = np.logical_and.reduce([np.isfinite(value) for value, _c in terms])
            grown += int((np.isinf(out[:, i]) & finite).sum())
    store_fields(block, [name for names in vectors for name in names], out.reshape(count * width, k))
    return grown


def transform_columns(columns: dict, transform: Transform) -> int:
    """Apply ``transform`` to writeable ``columns`` in place.

    Parameters
    ----------
    columns : dict of str to (N,) float32 ndarray
        Writeable; positions, motion, rotations, omega and scales are rewritten.
    transform : Transform

    Returns
    -------
    int
        Values that were finite and no longer fit float32 (now infinite).
    """
    apply = block_transformer(transform)
    grown = sum(run_blocks(len(columns["x"]), lambda part: apply({name: columns[name][part] for name in COLUMNS_MOVED})))
    rotate_sh(columns, transform)
    return grown


#: The columns :func:`block_transformer` rewrites (and reads).
COLUMNS_MOVED = POSITION + MOTION + ROTATION + OMEGA + SCALE

#: Rows of SH bands turned at a time: bounds the float64 temporaries.
_SH_BLOCK = 1 << 15


def rotate_sh(columns: dict, transform: Transform) -> None:
    """Turn the SH bands of ``columns`` (when it holds any) by the transform's rotation: their columns are
    replaced in the dict by new ones. A scale or a translation leaves them as they are."""
    degree = sh_degree(columns)
    if not degree or np.array_equal(np.asarray(transform.matrix), np.eye(3)):
        return
    k = SH_COEFFS[degree]
    names = sh_names(degree)
    m = sh.rotation_matrix(np.asarray(transform.matrix), degree)
    n = len(columns["x"])
    out = np.empty((3 * k, n), dtype=np.float32)
    sources = [np.asarray(columns[name]) for name in names]

    def job(part):
        block = np.stack([src[part] for src in sources]).astype(np.float64).reshape(3, k, -1)
        with np.errstate(over="ignore", invalid="ignore"):
            out[:, part] = np.einsum("jk,ckn->cjn", m, block).reshape(3 * k, -1)

    run_blocks(n, job, _SH_BLOCK)
    for i, name in enumerate(names):
        columns[name] = out[i]


def block_transformer(transform: Transform):
    """A function that transforms one block of rows in place and returns its overflow count."""
    linear = transform.linear()
    rotates = not np.array_equal(np.asarray(transform.matrix), np.eye(3))
    scales = transform.scale != 1.0
    offset = np.asarray(transform.translation)
    left = left_product_matrix(transform.rotation)
    log_scale = math.log(transform.scale)

    identity = np.eye(len(SCALE))

    def apply(block: dict) -> int:
        grown = 0
        # NaN and inf go through as they are; an overflow raises and is counted where it happens.
        with np.errstate(over="raise", invalid="ignore"):
            if rotates or scales:
                grown += _affine_group(block, (POSITION, MOTION[0:3], MOTION[3:6], MOTION[6:9]), linear, offset)
            elif offset.any():
                grown += _affine_group(block, (POSITION,), identity, offset)
            if rotates:
                grown += _affine_group(block, (ROTATION, OMEGA), left)
            if scales:
                grown += _affine_group(block, (SCALE,), identity, np.full(len(SCALE), log_scale))
        return grown

    return apply


def transform_cameras(cameras, transform: Transform):
    """Cameras (``cameras.json`` form) moved with the scene: centre R S c + T, rotation R @ rotation.

    Returns new dicts (other keys copied); None stays None.

    Raises
    ------
    UnsupportedError
        For a camera the transform moves past what a double holds (a camera file
        holds finite numbers only; an infinite centre places the viewer nowhere).
    """
    if cameras is None:
        return None
    out = []
    r = np.asarray(transform.matrix)
    for i, cam in enumerate(cameras):
        moved = dict(cam)
        position = transform.apply_points(np.asarray([cam["position"]]))[0]
        with np.errstate(over="ignore", invalid="ignore"):
            rotation = r @ np.asarray(cam["rotation"], dtype=np.float64)
        if not (np.isfinite(position).all() and np.isfinite(rotation).all()):
            raise UnsupportedError(f"the transform ({transform.describe()}) moves it past what a double holds "
                                   f"({float(np.finfo(np.float64).max):.3g})", where=(f"camera {i}",))
        moved["position"] = [float(v) for v in position]
        moved["rotation"] = [[float(v) for v in row] for row in rotation]
        out.append(moved)
    return out


def apply_transform(scene: Scene, transform: Transform) -> tuple[Scene, OpReport]:
    """Move, turn and scale a scene and its cameras: p' = R (S p) + T at every time.

    Positions, all nine motion coefficients, rest rotations, angular velocities
    (omega), scales and stored cameras are transformed so that the new scene
    drawn from the moved camera at any time is the old scene drawn from the old
    camera (see the module docstring). Non-finite values stay non-finite.

    Parameters
    ----------
    scene : Scene
    transform : Transform
        From :func:`make_transform` or built directly.

    Returns
    -------
    (Scene, OpReport)
        A new scene (no splat removed).
    """
    cameras = transform_cameras(scene.cameras, transform)  # first: a camera it cannot move is refused at once
    columns, grown = copy_rows(scene.columns, each=block_transformer(transform))
    rotate_sh(columns, transform)
    report = transform_report(scene.count, len(cameras or []), transform, grown, scene.sh_degree > 0)
    return derive(scene, columns, report.notes, cameras=cameras), report


def transform_report(count: int, cameras: int, transform: Transform, grown: int, sh_bands: bool = False) -> OpReport:
    """The report of :func:`apply_transform`."""
    report = OpReport("transform", count, count)
    moved = f" and {cameras:,} camera{'' if cameras == 1 else 's'}" if cameras else ""
    rotates = not np.array_equal(np.asarray(transform.matrix), np.eye(3))
    changed = ["positions"] + (["motion"] if rotates or transform.scale != 1.0 else []) + (
        ["rotations", "omega"] if rotates else []) + (["scales"] if transform.scale != 1.0 else []) + (
        ["SH bands"] if rotates and sh_bands else [])
    report.notes.append(f"transform: p' = R(S p) + T with {transform.describe()} applied to {plural(count, 'splat')}"
                        f"{moved} ({', '.join(changed)})")
    if grown:
        report.notes.append(f"transform: {grown:,} finite values grew beyond float32 and are now infinite")
    report.counts = {"cameras": cameras, "overflow": grown}
    return report


__all__ = ["Transform", "make_transform", "parse_rotation", "axis_rotation", "compose_rotation",
           "quaternion_matrix", "left_product_matrix", "transform_columns", "rotate_sh", "transform_cameras",
           "apply_transform"]
