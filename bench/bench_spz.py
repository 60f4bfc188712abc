"""1M static SH-degree-3 3DGS PLY -> .splat and -> .spz: splatconv's time, side by side with gaussforge's.

Usage: python bench/bench_spz.py [SPLATS]. Makes the PLY in a temporary folder (random splats, all
45 f_rest_*) and, for each output, times:

* in process: ``io.write(io.read(src), out)`` (read, encode, write the file atomically) against
  gaussforge's ``convert`` of the same bytes (PLY -> .splat, -> .spz v4) after reading the file into
  memory, when the ``gaussforge`` package is importable here (put ``/tmp/libvenv``'s site-packages
  on ``PYTHONPATH``);
* in a fresh process, start-up and imports included: ``splatconv convert -q SRC OUT --force``
  against a fresh ``python -c`` that imports gaussforge, reads the file, converts and writes the
  output, run by the interpreter ``$GAUSSFORGE_PYTHON`` (default ``/tmp/libvenv/bin/python``) when
  it imports gaussforge; and the start-up alone (``splatconv --help``).

Figures: seconds, best of three, and the ratio to gaussforge; gaussforge is said to be absent when
it is. Measured in one run, side by side: on a shared machine the ratios are steadier than the
seconds. Figures from the shared two-core VM are in ``bench/README.md``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from splatconv import io, model

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _harness import CLI, best_seconds as best, run_fresh  # noqa: E402

#: The interpreter that runs gaussforge in a fresh process.
GAUSSFORGE_PYTHON = os.environ.get("GAUSSFORGE_PYTHON", "/tmp/libvenv/bin/python")
#: gaussforge's whole command in a fresh process: read argv[1], convert to format argv[3], write argv[2].
GAUSSFORGE_SNIPPET = """\
import sys
import gaussforge
src, out, fmt = sys.argv[1:4]
with open(src, "rb") as f:
    data = f.read()
result = gaussforge.GaussForge().convert(data, "ply", fmt, **({"spz_version": 4} if fmt == "spz" else {}))
if result.get("error"):
    raise SystemExit(result["error"])
with open(out, "wb") as f:
    f.write(result["data"])
"""


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


def fresh_gaussforge() -> bool:
    """Whether :data:`GAUSSFORGE_PYTHON` runs and imports gaussforge."""
    try:
        return subprocess.run([GAUSSFORGE_PYTHON, "-c", "import gaussforge"], capture_output=True).returncode == 0
    except OSError:
        return False


def best_fresh(argv: list, repeat: int = 3) -> float:
    """Least wall seconds of ``repeat`` fresh-process runs of ``argv`` (which must succeed)."""
    return min(run_fresh(argv, stdout="discard", check=True)["wall"] for _ in range(repeat))


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
    # An installed package runs from compiled modules: let the fresh processes keep theirs (a
    # PYTHONDONTWRITEBYTECODE environment would have every run compile splatconv's sources again).
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "sh3.ply"
        make_ply(src, n)
        try:
            import gaussforge
            forge = gaussforge.GaussForge()
        except ImportError:
            forge = None
            print("gaussforge: not importable here (put /tmp/libvenv's site-packages on PYTHONPATH); "
                  "in-process figures without it")
        fresh = fresh_gaussforge()
        if not fresh:
            print(f"gaussforge: {GAUSSFORGE_PYTHON} does not import it; fresh-process figures without it")
        start = best_fresh([CLI, "--help"])
        print(f"start-up: splatconv --help {start:.2f} s (fresh process)")
        for suffix, gf_format, options in ((".splat", "splat", {}), (".spz", "spz", {"spz_version": 4})):
            out = Path(tmp) / f"out{suffix}"
            ours = best(lambda: io.write(io.read(src), out, force=True))
            line = f"{n:,} SH3 splats PLY -> {suffix}: in process: splatconv {ours:.2f} s, {out.stat().st_size:,} bytes"
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
            ours = best_fresh([CLI, "convert", "-q", str(src), str(out), "--force"])
            line = f"{n:,} SH3 splats PLY -> {suffix}: fresh process: splatconv convert {ours:.2f} s"
            if fresh:
                theirs_out = Path(tmp) / f"gaussforge{suffix}"
                t = best_fresh([GAUSSFORGE_PYTHON, "-c", GAUSSFORGE_SNIPPET, str(src), str(theirs_out), gf_format])
                line += f"; gaussforge {t:.2f} s; ratio {ours / t:.2f}x"
            print(line)


if __name__ == "__main__":
    main()
