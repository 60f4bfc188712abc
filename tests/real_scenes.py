"""Test scenes with what real trained Spacetime Gaussians scenes contain.

The bundled sample has none of this; real scenes from the wild have all of it:

* zero rotations with omega 0 (17-95% of a real scene; never drawn),
* a zero rotation whose omega is not 0 (zero at one instant only: drawn),
* NaN positions and NaN motion terms, huge positions,
* infinite temporal scales (drawn at every time),
* linear scales of exactly 0 (log scale -inf: a flat splat, drawn),
* opacities whose alpha byte is 0, NaN opacities,
* splats below the temporal cut over all of [0, 1],
* ``.splatv`` files whose texture data is shorter than the header's ``texheight``.

:func:`real_scene` builds such a scene in front of :data:`tests.scenes.CAMERA`
and says which rows are which (:class:`Rows`); :func:`unpadded_splatv` writes it
the way real files are written. :func:`real_file` reaches the real trained scenes
kept beside the repository (``../shared/real/``, never copied into it), and skips
plainly where they are absent (in CI, which has them, it fails instead).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from splatconv.formats import splatv
from splatconv.model import Scene

from .conftest import splatv_bytes
from .scenes import moving_scene


@dataclass
class Rows:
    """Row indices of each property planted in a :func:`real_scene` (disjoint)."""

    zero_rotation: np.ndarray      # rotation and omega all 0: undrawable
    zero_rotation_spinning: np.ndarray  # rotation 0, omega not: drawable
    nan_position: np.ndarray       # undrawable
    nan_motion: np.ndarray         # undrawable
    huge_position: np.ndarray      # finite, far away: drawable (off screen)
    infinite_trbf: np.ndarray      # drawn at every time
    flat: np.ndarray               # a linear scale of exactly 0: drawable
    alpha_zero: np.ndarray         # undrawable
    nan_opacity: np.ndarray        # stored as alpha 0: undrawable
    hidden_in_time: np.ndarray     # below the cut over [0, 1]: undrawable

    @property
    def undrawable(self) -> np.ndarray:
        return np.sort(np.concatenate([self.zero_rotation, self.nan_position, self.nan_motion, self.alpha_zero,
                                       self.nan_opacity, self.hidden_in_time]))

    @property
    def flat_or_infinite(self) -> np.ndarray:
        """Rows with an infinity that the viewer draws (flat splats, infinite trbf scales)."""
        return np.sort(np.concatenate([self.flat, self.infinite_trbf]))


def real_scene(n: int = 600, seed: int = 0, zero_share: float = 0.4) -> tuple[Scene, Rows]:
    """A moving scene with every property of real trained scenes (see the module docstring).

    ``zero_share`` of the rows get a zero rotation and omega; a handful of rows
    each get one of the other properties. Row 0 stays :func:`moving_scene`'s
    invisible far splat (alpha 0, listed in ``alpha_zero``).
    """
    scene = moving_scene(n, seed)
    c = scene.columns
    rng = np.random.default_rng(seed + 1000)
    rows = rng.permutation(np.arange(1, n))
    k = max(2, n // 60)
    picks = {}
    at = 0
    for name in ("zero_rotation_spinning", "nan_position", "nan_motion", "huge_position", "infinite_trbf", "flat",
                 "alpha_zero", "nan_opacity", "hidden_in_time"):
        picks[name] = np.sort(rows[at:at + k])
        at += k
    zero = int(zero_share * n)
    picks["zero_rotation"] = np.sort(rows[at:at + zero])
    for name in ("rot_0", "rot_1", "rot_2", "rot_3", "omega_0", "omega_1", "omega_2", "omega_3"):
        c[name][picks["zero_rotation"]] = 0.0
    for name in ("rot_0", "rot_1", "rot_2", "rot_3"):
        c[name][picks["zero_rotation_spinning"]] = 0.0
    c["omega_0"][picks["zero_rotation_spinning"]] = 1.5
    c["x"][picks["nan_position"][::2]] = np.nan
    c["z"][picks["nan_position"][1::2]] = np.nan
    c["motion_4"][picks["nan_motion"]] = np.nan
    c["x"][picks["huge_position"]] = np.float32(3e38)
    c["trbf_scale"][picks["infinite_trbf"]] = np.inf
    c["scale_1"][picks["flat"]] = -np.inf
    c["opacity"][picks["alpha_zero"]] = -30.0
    c["opacity"][picks["nan_opacity"]] = np.nan
    c["trbf_center"][picks["hidden_in_time"]] = rng.choice([-3.0, 4.0], k).astype(np.float32)
    c["trbf_scale"][picks["hidden_in_time"]] = np.float32(np.log(0.3))
    picks["alpha_zero"] = np.concatenate([[0], picks["alpha_zero"]])  # moving_scene's far splat has opacity -40
    return scene, Rows(**picks)


def unpadded_splatv(scene: Scene, path) -> None:
    """Write ``scene`` as a ``.splatv`` whose texture data stops after the last record (as real files do)."""
    records, _ = splatv.encode(scene)
    path.write_bytes(splatv_bytes(records[:scene.count], scene.cameras, pad=False))


#: Real trained scenes beside the repository (see the README there): read-only, never copied into it.
#: ``SPLATCONV_SHARED`` names the folder that holds them when the tests run from a copy of the
#: checkout (``.ci/run`` does), not from the checkout beside it.
REAL_FOLDER = (Path(os.environ["SPLATCONV_SHARED"]) if os.environ.get("SPLATCONV_SHARED")
               else Path(__file__).resolve().parent.parent.parent / "shared") / "real"


def real_file(name: str) -> Path:
    """The real trained scene ``name`` in :data:`REAL_FOLDER`; where it is absent the test is skipped,
    saying so, except in CI (``CI`` set), where it fails: CI has the folder and runs them."""
    path = REAL_FOLDER / name
    if not path.is_file():
        why = f"real scene {name} is absent ({REAL_FOLDER} is not part of the repository)"
        if os.environ.get("CI"):
            pytest.fail(why)
        pytest.skip(why)
    return path


__all__ = ["REAL_FOLDER", "Rows", "real_file", "real_scene", "unpadded_splatv"]
