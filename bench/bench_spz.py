"""1M static SH-degree-3 3DGS PLY -> .splat and -> .spz: splatconv's time, side by side with gaussforge's.

Usage: python bench/bench_spz.py [SPLATS]. Makes the PLY in a temporary folder (random splats, all
45 f_rest_*), times ``splatconv convert`` (read, encode, write) to each format, and, when the
``gaussforge`` package is importable, its ``convert`` of the same bytes (PLY -> .splat, -> .spz v4)
after reading the file into memory. Figures: seconds, best of three, and the ratio to gaussforge.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from splatconv import io, model


def make_ply(path: Path, n: int) -> None:
    rng = np.random.default_rng(1)
    names = ["x", "y", "z", "nx", "ny", "nz", *model.COLOR, *model.SH_REST, "opacity", *model.SCALE,
             *model.ROTATION]
    d = np.zeros(n, dtype=[(k, "<f4") for k in names])
    for k in model.POSITION:
        d[k] = rng.uniform(-3, 3, n)
    for k in model.COLOR:
        d[k] = rng.normal(0, 1, n)
    for k in model.SH_REST:
        d[k] = rng.normal(0, 0.2, n)
    d["opacity"] = rng.normal(0, 2, n)
    for k in model.SCALE:
        d[k] = rng.uniform(-6, -2, n)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    for i, k in enumerate(model.ROTATION):
        d[k] = q[:, i]
    head = f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\n" + "".join(
        f"property float {k}\n" for k in names) + "end_header\n"
    path.write_bytes(head.encode() + d.tobytes())


def best(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "sh3.ply"
        make_ply(src, n)
        try:
            import gaussforge
            forge = gaussforge.GaussForge()
        except ImportError:
            forge = None
        for suffix, gf_format, options in ((".splat", "splat", {}), (".spz", "spz", {"spz_version": 4})):
            out = Path(tmp) / f"out{suffix}"
            ours = best(lambda: io.write(io.read(src), out, force=True))
            line = f"{n:,} SH3 splats PLY -> {suffix}: splatconv {ours:.2f} s, {out.stat().st_size:,} bytes"
            if forge is not None:
                def theirs():
                    result = forge.convert(src.read_bytes(), "ply", gf_format, **options)
                    if "error" in result and result["error"]:
                        raise RuntimeError(result["error"])
                    return result
                t = best(theirs)
                size = len(theirs()["data"])
                line += f"; gaussforge {t:.2f} s, {size:,} bytes; ratio {ours / t:.2f}x"
            print(line)


if __name__ == "__main__":
    main()
