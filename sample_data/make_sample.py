"""Generate the ``dancers`` sample scene: a small animated Spacetime Gaussians PLY.

The scene is about 5000 splats in the Spacetime Gaussians *lite* PLY layout,
arranged so that every temporal term of the model visibly does something over
the time range t in [0, 1]:

* **ground** - a static grey disc of flat splats at y = +1 (below everything,
  since world "up" is -y), with concentric light/dark bands so the perspective
  reads. A wide temporal basis keeps it visible at every t.
* **ball** - a red sphere that travels along a curved path from left to right:
  linear (``motion_0..2``), quadratic (``motion_3..5``, the hop) and cubic
  (``motion_6..8``, the ease-in/out and the S-bend in depth) motion terms.
* **bar** - a green elongated box that spins about the z axis through
  120 degrees: each splat's orientation turns through the angular velocity term
  (``omega_0..3``), and the splat centres follow the same rotation via a cubic
  fit in ``motion_*``, so the bar turns as one rigid piece.
* **blue** - a blue cloud that fades in and out around t = 0.3 (narrow temporal
  basis: ``trbf_center`` and a small ``trbf_scale``).
* **burst** - a yellow shell that appears late (centred on t = 0.9) and expands
  as it appears: per-splat radial linear motion with a late ``trbf_center``.

It also writes three cameras in the 3DGS ``cameras.json`` form looking at the
origin from about 6 units away, camera 0 roughly frontal.

Regenerate with::

    python sample_data/make_sample.py

which writes ``dancers.ply`` and ``cameras.json`` next to this script. The
output is deterministic (fixed seed, explicit little-endian float32, no
timestamps), so re-running it reproduces the committed files byte for byte.
Only numpy and the standard library are needed.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

SEED = 20240601

#: Property names of the lite PLY layout, in file order.
PROPERTIES = (
    ["x", "y", "z", "trbf_center", "trbf_scale", "nx", "ny", "nz"]
    + [f"motion_{i}" for i in range(9)]
    + ["f_dc_0", "f_dc_1", "f_dc_2", "opacity"]
    + ["scale_0", "scale_1", "scale_2"]
    + ["rot_0", "rot_1", "rot_2", "rot_3"]
    + ["omega_0", "omega_1", "omega_2", "omega_3"]
)
ROW_DTYPE = np.dtype([(name, "<f4") for name in PROPERTIES])


# ---------------------------------------------------------------------------
# Small vectorised helpers
# ---------------------------------------------------------------------------

def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions in (w, x, y, z) order.

    Parameters
    ----------
    a, b : (..., 4) ndarray
        Quaternions; broadcast against each other.

    Returns
    -------
    (..., 4) ndarray
        ``a * b`` (apply ``b`` first, then ``a``).
    """
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def random_unit_quats(rng: np.random.Generator, n: int) -> np.ndarray:
    """Uniformly random unit quaternions, ``(n, 4)``, with w >= 0.

    A normalised 4D Gaussian sample is uniform on the 3-sphere; flipping to
    w >= 0 only picks one of the two equivalent signs.
    """
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def yaw_quats(angle: np.ndarray) -> np.ndarray:
    """Quaternions for rotations by ``angle`` radians about the world y axis."""
    half = 0.5 * np.asarray(angle)
    zero = np.zeros_like(half)
    return np.stack([np.cos(half), zero, np.sin(half), zero], axis=-1)


def jittered_colour(rng: np.random.Generator, rgb, n: int, sigma: float = 0.03) -> np.ndarray:
    """``(n, 3)`` RGB around ``rgb`` with Gaussian jitter, clipped to [0, 1]."""
    return np.clip(np.asarray(rgb, dtype=np.float64) + rng.normal(0.0, sigma, size=(n, 3)), 0.0, 1.0)


def log_scales(rng: np.random.Generator, sizes, n: int, spread: float = 0.15) -> np.ndarray:
    """``(n, 3)`` log scales around per-axis ``sizes`` (world units).

    The multiplicative jitter (``exp(N(0, spread))``) keeps splats from looking
    like a regular lattice while staying near the requested size.
    """
    return np.log(np.asarray(sizes, dtype=np.float64)) + rng.normal(0.0, spread, size=(n, 3))


def sphere_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    """``(n, 3)`` unit vectors uniform on the sphere."""
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def new_rows(n: int) -> np.ndarray:
    """A zeroed ``(n,)`` structured array of PLY rows.

    Zero is the right default for the normals, motion and omega of static splats.
    """
    return np.zeros(n, dtype=ROW_DTYPE)


def fill_common(rows, pos, trbf_center, trbf_scale, rgb, logit_opacity, log_scale, quat):
    """Write the per-splat attributes every shape has into ``rows`` in place.

    Parameters
    ----------
    rows : (n,) structured ndarray of ``ROW_DTYPE``
    pos : (n, 3) ndarray
        Centres at dt = 0 (time ``trbf_center``).
    trbf_center, trbf_scale : float or (n,) ndarray
        Temporal centre and log temporal width.
    rgb : (n, 3) ndarray
        Colour in [0, 1].
    logit_opacity : (n,) ndarray
    log_scale : (n, 3) ndarray
    quat : (n, 4) ndarray
        Orientation at dt = 0, (w, x, y, z).
    """
    rows["x"], rows["y"], rows["z"] = pos.T
    rows["trbf_center"] = trbf_center
    rows["trbf_scale"] = trbf_scale
    rows["f_dc_0"], rows["f_dc_1"], rows["f_dc_2"] = rgb.T
    rows["opacity"] = logit_opacity
    rows["scale_0"], rows["scale_1"], rows["scale_2"] = log_scale.T
    rows["rot_0"], rows["rot_1"], rows["rot_2"], rows["rot_3"] = quat.T


def set_motion(rows, lin, quad, cubic):
    """Write the motion polynomial coefficients, each ``(n, 3)`` or ``(3,)``."""
    for base, coeff in ((0, lin), (3, quad), (6, cubic)):
        coeff = np.broadcast_to(np.asarray(coeff, dtype=np.float64), (len(rows), 3))
        for axis in range(3):
            rows[f"motion_{base + axis}"] = coeff[:, axis]


# ---------------------------------------------------------------------------
# Shapes
# ---------------------------------------------------------------------------

def make_ground(rng: np.random.Generator, n: int = 1800) -> np.ndarray:
    """Static grey disc of radius 2 at y = +1 (below the scene; up is -y).

    The splats are flat (thin along y) with random yaw, and alternate light and
    dark bands every 0.4 units of radius give a visual ruler. ``trbf_scale`` =
    log(10) makes the temporal opacity >= 0.997 for all t in [0, 1].
    """
    radius = 2.0 * np.sqrt(rng.random(n))  # sqrt: uniform density over the area
    theta = rng.uniform(0.0, 2.0 * np.pi, n)
    pos = np.stack([radius * np.cos(theta), np.full(n, 1.0), radius * np.sin(theta)], axis=1)
    pos[:, 1] += rng.normal(0.0, 0.005, n)
    band = np.floor(radius / 0.4) % 2
    grey = np.where(band == 0, 0.42, 0.58)[:, None] * np.ones(3)
    rows = new_rows(n)
    fill_common(
        rows, pos, 0.5, math.log(10.0),
        rgb=np.clip(grey + rng.normal(0.0, 0.02, size=(n, 3)), 0.0, 1.0),
        logit_opacity=rng.uniform(3.0, 4.0, n),
        log_scale=log_scales(rng, (0.06, 0.02, 0.06), n),
        quat=yaw_quats(rng.uniform(0.0, np.pi, n)),
    )
    return rows


def make_ball(rng: np.random.Generator, n: int = 1000) -> np.ndarray:
    """Red ball of radius 0.25 travelling along a curved path.

    All splats share ``trbf_center`` = 0.5 so one motion polynomial moves them
    rigidly; dt runs over [-0.5, 0.5]. The path, relative to the centre
    (0, -0.6, -0.4) at t = 0.5, is::

        x(dt) = 3.6 dt            - 2.4 dt^3   # -1.5 -> 1.5, fast mid-way (cubic)
        y(dt) =          1.6 dt^2              # hop: highest (most -y) at t = 0.5
        z(dt) = 0.5 dt            - 4.0 dt^3   # S-bend in depth (cubic)

    ``trbf_scale`` = log(2) keeps temporal opacity >= 0.94 over the whole range.
    """
    centre = np.array([0.0, -0.6, -0.4])
    # Mostly a surface shell (what a trained model would learn) plus a filled core.
    shell = rng.random(n) < 0.8
    r = np.where(shell, 0.25 + rng.normal(0.0, 0.008, n), 0.22 * np.cbrt(rng.random(n)))
    pos = centre + sphere_directions(rng, n) * r[:, None]
    rows = new_rows(n)
    fill_common(
        rows, pos, 0.5, math.log(2.0),
        rgb=jittered_colour(rng, (0.90, 0.12, 0.10), n),
        logit_opacity=rng.uniform(2.5, 4.0, n),
        log_scale=log_scales(rng, (0.04, 0.03, 0.02), n),
        quat=random_unit_quats(rng, n),
    )
    set_motion(rows, lin=(3.6, 0.0, 0.5), quad=(0.0, 1.6, 0.0), cubic=(-2.4, 0.0, -4.0))
    return rows


def rotation_fit(k: float, half_range: float = 0.5, samples: int = 101):
    """Cubic fits of cos(theta(dt)) - 1 and sin(theta(dt)) for the omega spin.

    With ``rot = q0`` and ``omega = (0, k n) * q0`` the viewer's normalised
    quaternion ``q0 + omega dt`` is ``q0`` followed by a rotation about ``n`` by
    ``theta(dt) = 2 atan(k dt)``. Splat centres must turn through the same angle
    for the object to spin rigidly, but they can only move along a cubic in dt,
    so fit one (least squares, no constant term so ``xyz`` stays exact at dt = 0).

    Parameters
    ----------
    k : float
        Angular velocity magnitude put in ``omega``.
    half_range : float
        Fit over dt in [-half_range, half_range].
    samples : int
        Number of dt samples.

    Returns
    -------
    cos_coeffs, sin_coeffs : (3,) ndarray
        Coefficients of dt, dt^2, dt^3 for cos(theta) - 1 and sin(theta).
    max_error : float
        Largest deviation of the fits over the samples (per unit radius).
    """
    dt = np.linspace(-half_range, half_range, samples)
    theta = 2.0 * np.arctan(k * dt)
    basis = np.stack([dt, dt ** 2, dt ** 3], axis=1)
    targets = np.stack([np.cos(theta) - 1.0, np.sin(theta)], axis=1)
    coeffs, *_ = np.linalg.lstsq(basis, targets, rcond=None)
    max_error = float(np.abs(basis @ coeffs - targets).max())
    return coeffs[:, 0], coeffs[:, 1], max_error


def make_bar(rng: np.random.Generator, n: int = 900) -> np.ndarray:
    """Green 1.4 x 0.16 x 0.16 bar spinning about the z axis (like a clock hand).

    Orientation: identity base orientation (splats elongated along the bar's
    x axis) plus ``omega = (0, 0, 0, k)``, so the quaternion turns by
    2 atan(k dt), from -60 to +60 degrees over t in [0, 1]. Position: Rodrigues'
    formula for the same rotation, ``p(dt) = p0 + (cos - 1) u_perp + sin (n x u)``
    with ``u = p0 - centre``, where cos - 1 and sin are the cubic fits of
    :func:`rotation_fit`; the motion coefficients are those fits times each
    splat's ``u_perp`` and ``n x u``. Over the sweep the fitted centres stay
    within 1.7 degrees and 2.6% of radius of the exact rotation.
    """
    centre = np.array([0.0, -0.5, 0.9])
    axis = np.array([0.0, 0.0, 1.0])
    # theta(+-0.5) = +-60 degrees. Beyond that the cubic fit of the centres drifts
    # visibly from the splat orientations (about 6 degrees off at +-80).
    k = 2.0 * math.tan(math.radians(60.0) / 2.0)
    half = np.array([0.7, 0.08, 0.08])
    u = rng.uniform(-1.0, 1.0, size=(n, 3)) * half
    pos = centre + u
    rows = new_rows(n)
    fill_common(
        rows, pos, 0.5, math.log(2.0),
        rgb=jittered_colour(rng, (0.12, 0.80, 0.20), n),
        logit_opacity=rng.uniform(2.5, 4.0, n),
        log_scale=log_scales(rng, (0.06, 0.025, 0.025), n),
        quat=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
    )
    q0 = np.stack([rows[f"rot_{i}"] for i in range(4)], axis=1).astype(np.float64)
    omega = quat_multiply(np.concatenate([[0.0], k * axis]), q0)
    rows["omega_0"], rows["omega_1"], rows["omega_2"], rows["omega_3"] = omega.T

    cos_c, sin_c, _ = rotation_fit(k)
    u_perp = u - np.outer(u @ axis, axis)
    n_cross_u = np.cross(axis, u)
    # Term j (dt^(j+1)) of the Rodrigues expansion, one (n, 3) vector per power.
    lin, quad, cubic = (u_perp * cos_c[j] + n_cross_u * sin_c[j] for j in range(3))
    set_motion(rows, lin, quad, cubic)
    return rows


def make_blue(rng: np.random.Generator, n: int = 700) -> np.ndarray:
    """Static blue Gaussian cloud that fades in and out, peaking at t = 0.3.

    ``trbf_scale`` = log(0.12) gives a temporal half-width of 0.12, so the cloud
    is drawn only for t in about [0.06, 0.54] (temporal opacity >= 0.02).
    """
    pos = np.array([-1.2, -0.2, 0.4]) + rng.normal(0.0, 0.18, size=(n, 3))
    rows = new_rows(n)
    fill_common(
        rows, pos, 0.3, math.log(0.12),
        rgb=jittered_colour(rng, (0.15, 0.30, 0.95), n),
        logit_opacity=rng.uniform(2.0, 3.5, n),
        log_scale=log_scales(rng, (0.04, 0.04, 0.04), n, spread=0.25),
        quat=random_unit_quats(rng, n),
    )
    return rows


def make_burst(rng: np.random.Generator, n: int = 600) -> np.ndarray:
    """Yellow shell that appears late and expands while it appears.

    ``trbf_center`` = 0.9 and ``trbf_scale`` = log(0.2): drawn from t of about
    0.5 on, fully opaque at t = 0.9. Each splat has its own linear motion along
    its radial direction, so the shell radius is 0.4 + 0.8 dt: 0.08 when it
    first shows, 0.48 at t = 1.
    """
    centre = np.array([1.2, -0.3, 0.4])
    d = sphere_directions(rng, n)
    pos = centre + 0.4 * d
    rows = new_rows(n)
    fill_common(
        rows, pos, 0.9, math.log(0.2),
        rgb=jittered_colour(rng, (0.95, 0.85, 0.10), n),
        logit_opacity=rng.uniform(2.5, 4.0, n),
        log_scale=log_scales(rng, (0.03, 0.03, 0.02), n),
        quat=random_unit_quats(rng, n),
    )
    set_motion(rows, lin=0.8 * d, quad=(0.0, 0.0, 0.0), cubic=(0.0, 0.0, 0.0))
    return rows


# ---------------------------------------------------------------------------
# Cameras
# ---------------------------------------------------------------------------

def look_at_camera(cam_id: int, position, focal: float, width: int = 1280, height: int = 720) -> dict:
    """A ``cameras.json`` entry at ``position`` looking at the origin.

    The rotation's columns are the camera's right (x), down (y) and forward (z)
    axes in world coordinates (OpenCV convention). World "down" is +y, so the
    right axis is down x forward and the camera has no roll.
    """
    c = np.asarray(position, dtype=np.float64)
    forward = -c / np.linalg.norm(c)
    right = np.cross([0.0, 1.0, 0.0], forward)
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    rotation = np.stack([right, down, forward], axis=1)

    def tidy(v: float) -> float:
        # + 0.0 turns -0.0 into 0.0 so the JSON shows no "-0.0".
        return round(float(v), 6) + 0.0

    return {
        "id": cam_id,
        "img_name": f"cam{cam_id:02d}",
        "width": width,
        "height": height,
        "position": [tidy(v) for v in c],
        "rotation": [[tidy(v) for v in row] for row in rotation],
        "fy": float(focal),
        "fx": float(focal),
    }


def orbit_position(distance: float, azimuth_deg: float, elevation_deg: float) -> list:
    """Camera centre on a sphere round the origin: azimuth 0 is on -z, elevation raises along -y."""
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    return [distance * math.sin(az) * math.cos(el),
            -distance * math.sin(el),
            -distance * math.cos(az) * math.cos(el)]


def make_cameras() -> list:
    """Three cameras about 6 units out: frontal, from the right, from the left and higher."""
    return [
        look_at_camera(0, orbit_position(6.0, 0.0, 12.0), 1000.0),
        look_at_camera(1, orbit_position(6.5, 30.0, 18.0), 1050.0),
        look_at_camera(2, orbit_position(6.0, -35.0, 25.0), 900.0),
    ]


# ---------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------

def ply_bytes(rows: np.ndarray) -> bytes:
    """Serialise rows as a binary little-endian PLY with one ``vertex`` element."""
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(rows)}"]
    header += [f"property float {name}" for name in PROPERTIES]
    header.append("end_header")
    return ("\n".join(header) + "\n").encode("ascii") + rows.astype(ROW_DTYPE, copy=False).tobytes()


def build_scene(seed: int = SEED) -> np.ndarray:
    """All splats of the scene as one structured array, shapes in a fixed order."""
    rng = np.random.default_rng(seed)
    # Fixed call order: each shape draws from the same generator in turn.
    shapes = [make_ground, make_ball, make_bar, make_blue, make_burst]
    return np.concatenate([make(rng) for make in shapes])


def main() -> None:
    """Write ``dancers.ply`` and ``cameras.json`` next to this script."""
    out_dir = Path(__file__).resolve().parent
    rows = build_scene()
    (out_dir / "dancers.ply").write_bytes(ply_bytes(rows))
    with open(out_dir / "cameras.json", "w", encoding="utf-8", newline="\n") as f:
        json.dump(make_cameras(), f, indent=2)
        f.write("\n")
    print(f"wrote {len(rows)} splats to {out_dir / 'dancers.ply'} and 3 cameras to {out_dir / 'cameras.json'}")


if __name__ == "__main__":
    main()
