"""Real spherical harmonics of degrees 1 to 3 as 3DGS evaluates them, and their rotation.

A scene's optional SH bands (:data:`splatconv.model.SH_REST`) hold, for each colour
channel, the coefficients of the 3DGS basis below (the viewer draws degree 0 only;
other tools draw them all). Turning a scene by R must turn each splat's colour
function with it: the new coefficients c' satisfy f'(R d) = f(d) for every direction
d. Each degree l is closed under rotation, so c'_l = D_l c_l for a
``(2l+1, 2l+1)`` matrix D_l (the real Wigner D matrix of R in this basis), found
here by least squares over a fixed set of directions well spread over the sphere
(exact to float64 rounding: the 2l+1 basis functions are independent on them).
"""

from __future__ import annotations

import numpy as np

#: The 3DGS basis constants (``eval_sh`` of the reference implementation), degree by degree.
_C1 = 0.4886025119029199
_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396)
_C3 = (-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154, -0.4570457994644658,
       1.445305721320277, -0.5900435899266435)
#: Basis functions of each degree, in coefficient order.
DEGREE_SIZES = (3, 5, 7)


def basis(dirs: np.ndarray, degree: int) -> np.ndarray:
    """The basis functions of degrees 1 to ``degree`` at unit directions ``dirs`` ``(M, 3)``:
    ``(M, K) float64``, K = 3, 8 or 15, in 3DGS coefficient order (``f_rest`` k of a channel)."""
    d = np.asarray(dirs, dtype=np.float64)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    out = [-_C1 * y, _C1 * z, -_C1 * x]
    if degree >= 2:
        xx, yy, zz = x * x, y * y, z * z
        out += [_C2[0] * x * y, _C2[1] * y * z, _C2[2] * (2 * zz - xx - yy), _C2[3] * x * z, _C2[4] * (xx - yy)]
    if degree >= 3:
        out += [_C3[0] * y * (3 * xx - yy), _C3[1] * x * y * z, _C3[2] * y * (4 * zz - xx - yy),
                _C3[3] * z * (2 * zz - 3 * xx - 3 * yy), _C3[4] * x * (4 * zz - xx - yy), _C3[5] * z * (xx - yy),
                _C3[6] * x * (xx - 3 * yy)]
    return np.stack(out[:sum(DEGREE_SIZES[:degree])], axis=1)


def _directions(count: int = 64) -> np.ndarray:
    """``count`` unit directions spread evenly over the sphere (a Fibonacci lattice): ``(count, 3)``."""
    i = np.arange(count) + 0.5
    z = 1.0 - 2.0 * i / count
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + 5.0 ** 0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def rotation_matrix(matrix: np.ndarray, degree: int) -> np.ndarray:
    """The ``(K, K) float64`` matrix M that turns one channel's coefficients ``c`` (degrees 1 to
    ``degree``, 3DGS order) by the rotation ``matrix`` (3 x 3, rotating column vectors): the colour
    function of ``M @ c`` at ``matrix @ d`` equals that of ``c`` at ``d``. Block diagonal by degree."""
    r = np.asarray(matrix, dtype=np.float64)
    dirs = _directions()
    size = sum(DEGREE_SIZES[:degree])
    out = np.zeros((size, size))
    start = 0
    for l in range(1, degree + 1):
        block = slice(start, start + DEGREE_SIZES[l - 1])
        here = basis(dirs, l)[:, block]
        # f'(d) = f(R^T d): sample the old basis at R^T d (the rows d @ R) and express it in the new one.
        turned = basis(dirs @ r, l)[:, block]
        solution, *_ = np.linalg.lstsq(here, turned, rcond=None)
        out[block, block] = solution
        start = block.stop
    return out


def evaluate(coeffs: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """The view-dependent part of each splat's colour at its direction: ``sum_k c[n, ch, k] Y_k(d_n)``.

    Parameters
    ----------
    coeffs : (N, 3, K) ndarray
        Per splat and channel, the coefficients of degrees 1 up (K = 3, 8 or 15).
    dirs : (N, 3) ndarray
        Unit directions.

    Returns
    -------
    (N, 3) float64
    """
    coeffs = np.asarray(coeffs, dtype=np.float64)
    degree = {3: 1, 8: 2, 15: 3}[coeffs.shape[2]]
    return np.einsum("nck,nk->nc", coeffs, basis(dirs, degree))
