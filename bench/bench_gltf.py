"""A real scene baked to a PLY, written as a .glb by splatconv and by PlayCanvas splat-transform: splat for splat.

Usage: python bench/bench_gltf.py [SCENE] [TIME]. Bakes SCENE (default ../shared/real/yellow_clip3.splatv, or
$SPLATCONV_REAL/yellow_clip3.splatv) at TIME (0.5) to a 3DGS PLY in a temporary folder, converts it to .glb with
``splatconv convert`` and with splat-transform ($SPLAT_TRANSFORM, else /tmp/st/node_modules/.bin/splat-transform),
reads both files' attributes as stored (no conversion back), pairs the splats by position and prints the largest
difference of each: positions, rotations (normalised, up to sign), linear scales, opacities, SH coefficients, and
both file sizes. Says plainly when the scene or splat-transform is absent.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from splatconv import io, model
from splatconv.formats import gltf

HERE = Path(__file__).resolve().parent
REAL = Path(os.environ.get("SPLATCONV_REAL", HERE.parent.parent / "shared" / "real"))
TOOL = os.environ.get("SPLAT_TRANSFORM", "/tmp/st/node_modules/.bin/splat-transform")


def attributes(path: Path) -> dict:
    """Each splat attribute of a .glb as it stores it: name -> (N, width) float32 (COLOR_0: its integers)."""
    src = gltf._Source(str(path))
    out = {name: gltf._values(view, slice(None)) for name, view in src.views.items()}
    if gltf.COLOR_0 in src.primitive["attributes"]:
        out[gltf.COLOR_0] = np.asarray(src._accessor(src.primitive["attributes"][gltf.COLOR_0], gltf.COLOR_0)[0])
    return out


def sh3_ply(path: Path, n: int = 20_000) -> None:
    """A static 3DGS PLY of ``n`` random splats with all 45 SH coefficients (what a bake cannot give)."""
    rng = np.random.default_rng(1)
    names = ["x", "y", "z", *model.COLOR, *model.SH_REST, "opacity", *model.SCALE, *model.ROTATION]
    d = np.zeros(n, dtype=[(k, "<f4") for k in names])
    for k in names:
        d[k] = rng.normal(0, 1, n)
    for k in model.SCALE:
        d[k] = rng.uniform(-6, -2, n)
    head = f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\n" + "".join(
        f"property float {k}\n" for k in names) + "end_header\n"
    path.write_bytes(head.encode() + d.tobytes())


def compare(ply: Path, label: str, tmp: Path) -> None:
    """Write ``ply`` as .glb both ways and print the largest differences and the sizes."""
    ours, theirs = tmp / f"{ply.stem}.ours.glb", tmp / f"{ply.stem}.st.glb"
    io.write(io.read(ply), ours)
    subprocess.run([TOOL, "-w", str(ply), str(theirs)], check=True, capture_output=True)
    a, b = attributes(ours), attributes(theirs)
    print(f"{label}: {len(a[gltf.POSITION]):,} splats; splat-transform wrote {len(b[gltf.POSITION]):,}")
    # Pair by position (either side may order the splats differently): sort both by position.
    ka = np.lexsort(a[gltf.POSITION].T[::-1])
    kb = np.lexsort(b[gltf.POSITION].T[::-1])
    a = {k: v[ka] for k, v in a.items()}
    b = {k: v[kb] for k, v in b.items()}
    rows = [("position", np.abs(a[gltf.POSITION] - b[gltf.POSITION]).max())]
    qa = a[gltf.ROTATION] / np.linalg.norm(a[gltf.ROTATION], axis=1, keepdims=True)
    qb = b[gltf.ROTATION] / np.linalg.norm(b[gltf.ROTATION], axis=1, keepdims=True)
    rows.append(("rotation (unit, up to sign)",
                 np.minimum(np.abs(qa - qb).max(axis=1), np.abs(qa + qb).max(axis=1)).max()))
    with np.errstate(invalid="ignore"):
        relative = np.abs(a[gltf.SCALE] - b[gltf.SCALE]) / np.abs(b[gltf.SCALE])
    rows.append(("scale (linear, relative)", np.nanmax(np.where(a[gltf.SCALE] == b[gltf.SCALE], 0, relative))))
    rows.append(("opacity", np.abs(a[gltf.OPACITY] - b[gltf.OPACITY]).max()))
    shared = [k for k in a if k.startswith(f"{gltf.EXTENSION}:SH_") and k in b]
    rows.append((f"SH ({len(shared)} coefficients)", max(np.abs(a[k] - b[k]).max() for k in shared)))
    rows.append(("COLOR_0 (byte steps)", np.abs(a[gltf.COLOR_0].astype(int) - b[gltf.COLOR_0].astype(int)).max()))
    for name, value in rows:
        print(f"  max difference, {name}: {value:.3g}")
    print(f"  sizes: splatconv {ours.stat().st_size:,} bytes, splat-transform {theirs.stat().st_size:,} bytes")


def main() -> None:
    scene = Path(sys.argv[1]) if len(sys.argv) > 1 else REAL / "yellow_clip3.splatv"
    time = sys.argv[2] if len(sys.argv) > 2 else "0.5"
    if not (shutil.which(TOOL) or os.path.exists(TOOL)) or not shutil.which("node"):
        print(f"absent: splat-transform at {TOOL} (or node); set SPLAT_TRANSFORM. Nothing compared.")
        return
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if scene.exists():
            ply = tmp / "baked.ply"
            subprocess.run([sys.executable, "-m", "splatconv", "bake", str(scene), str(ply), "--time", time,
                            "--quiet"], check=True)
            compare(ply, f"{scene.name} baked at t={time}", tmp)
        else:
            print(f"absent: {scene} (no real scene; set SPLATCONV_REAL or pass SCENE); the SH scene alone follows")
        ply = tmp / "sh3.ply"
        sh3_ply(ply)
        compare(ply, "random static scene with SH degree 3", tmp)


if __name__ == "__main__":
    main()
