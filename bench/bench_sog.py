"""`.sog` (PlayCanvas SOG v2): splatconv's encode and decode times, and the check against splat-transform.

1. Speed: a random static scene of N splats (default 1,000,000) written to ``.sog`` through the
   library (``io.write``: Morton order, codebooks, WebP, zip) and read back (``io.read``); with
   ``--sh3`` the same scene with SH degree 3 bands too (the palette's k-means tree).
2. Peers, when present: a real scene baked at t = 0.5 (``splatconv bake .../yellow_clip3.splatv
   y.ply --time 0.5``), PlayCanvas splat-transform's own ``.sog`` of that PLY (``-g cpu``), splatconv's
   ``.sog`` of it; both sizes; splat-transform reading splatconv's ``.sog`` back to PLY (its splat
   count), splatconv reading splat-transform's; and the fidelity of each decoded scene against the
   baked PLY (``splatconv verify ... --times 0.5``: the worst frame's PSNR from the file's cameras).
   Done means: splat-transform reads ours with every splat, draws it within 0.5 dB of its own
   ``.sog`` at no more than 1.1 times its size, and splatconv reads splat-transform's with every
   splat at the fidelity splat-transform itself reads it with.

splat-transform is found by ``$SPLAT_TRANSFORM`` or at /tmp/st/node_modules/.bin/splat-transform; the
real scene by ``$SPLATCONV_REAL`` or ../shared/real beside the repository (or /work/shared/real).
Either missing is said plainly and that part skipped. Run::

    python bench/bench_sog.py [--splats N] [--sh3] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402

from _harness import CLI, machine_line, row, work_folder  # noqa: E402
from splatconv import io, model  # noqa: E402
from splatconv.model import Scene  # noqa: E402

PEER_DEFAULT = "/tmp/st/node_modules/.bin/splat-transform"
SCENE = "yellow_clip3.splatv"


def random_scene(n: int, degree: int) -> Scene:
    """A plausible static scene: clustered positions, a spread of scales, colours, opacities, SH bands."""
    rng = np.random.default_rng(1)
    centres = rng.normal(0, 3, (256, 3))
    xyz = centres[rng.integers(0, 256, n)] + rng.normal(0, 0.4, (n, 3))
    cols = {name: xyz[:, i].astype(np.float32) for i, name in enumerate(model.POSITION)}
    for name in model.COLOR:
        cols[name] = rng.uniform(0, 1, n).astype(np.float32)
    cols["opacity"] = rng.normal(0, 2, n).astype(np.float32)
    for name in model.SCALE:
        cols[name] = rng.normal(-4.5, 1.0, n).astype(np.float32)
    q = rng.normal(size=(n, 4)).astype(np.float32)
    for i, name in enumerate(model.ROTATION):
        cols[name] = q[:, i]
    for name in model.sh_names(degree):
        cols[name] = rng.normal(0, 0.15, n).astype(np.float32)
    cols.update(model.static_columns(n))
    return Scene(columns=cols, variant=model.VARIANT_3DGS)


def speed(folder: str, n: int, degree: int) -> None:
    scene = random_scene(n, degree)
    path = os.path.join(folder, f"speed_sh{degree}.sog")
    start = time.perf_counter()
    io.write(scene, path, force=True)
    encode = time.perf_counter() - start
    start = time.perf_counter()
    back = io.read(path)
    decode = time.perf_counter() - start
    size = os.path.getsize(path)
    print(row(f"{n:,} splats, SH {degree}: encode", f"{encode:.1f} s", f"{size:,} bytes, {size / n:.1f} a splat"))
    print(row(f"{n:,} splats, SH {degree}: decode", f"{decode:.1f} s", f"{back.count:,} splats read"))


def _run(argv: list) -> subprocess.CompletedProcess:
    return subprocess.run(argv, capture_output=True, text=True)


def _count(ply: str) -> int:
    return io.read(ply).count


def _psnr(source: str, decoded: str) -> float:
    """The worst frame's PSNR of ``decoded`` against ``source`` at t = 0.5 (splatconv verify)."""
    done = _run([CLI, "verify", source, decoded, "--times", "0.5", "--json", "--quiet"])
    return min(frame["psnr"] for frame in json.loads(done.stdout)["frames"])


def _real_folder() -> str | None:
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    for folder in (os.environ.get("SPLATCONV_REAL"), os.path.join(here, "..", "shared", "real"), "/work/shared/real"):
        if folder and os.path.isfile(os.path.join(folder, SCENE)):
            return folder
    return None


def peers(folder: str) -> None:
    peer = os.environ.get("SPLAT_TRANSFORM", PEER_DEFAULT)
    real = _real_folder()
    if real is None:
        print(f"peer check skipped: the real scene {SCENE} is absent (set SPLATCONV_REAL)")
        return
    if not (shutil.which(peer) or os.path.isfile(peer)):
        print(f"peer check skipped: splat-transform is absent ({peer}; set SPLAT_TRANSFORM)")
        return
    at = lambda name: os.path.join(folder, name)  # noqa: E731
    baked = at("y.ply")
    _run([CLI, "bake", os.path.join(real, SCENE), baked, "--time", "0.5", "--force"])
    n = _count(baked)
    start = time.perf_counter()
    theirs = _run([peer, "-w", "-g", "cpu", baked, at("st.sog")])
    their_seconds = time.perf_counter() - start
    start = time.perf_counter()
    ours = _run([CLI, "convert", baked, at("ours.sog"), "--force"])
    our_seconds = time.perf_counter() - start
    if theirs.returncode or ours.returncode:
        print("peer check failed to write:", theirs.stderr[-400:], ours.stderr[-400:])
        return
    their_size, our_size = os.path.getsize(at("st.sog")), os.path.getsize(at("ours.sog"))
    _run([peer, "-w", at("st.sog"), at("st_reads_st.ply")])
    _run([peer, "-w", at("ours.sog"), at("st_reads_ours.ply")])
    counts = {"st_reads_ours": _count(at("st_reads_ours.ply")), "st_reads_st": _count(at("st_reads_st.ply")),
              "we_read_st": io.read(at("st.sog")).count, "we_read_ours": io.read(at("ours.sog")).count}
    psnr = {"st_reads_st": _psnr(baked, at("st_reads_st.ply")), "st_reads_ours": _psnr(baked, at("st_reads_ours.ply")),
            "we_read_st": _psnr(baked, at("st.sog")), "we_read_ours": _psnr(baked, at("ours.sog"))}
    print(f"peer check: {SCENE} baked at t=0.5, {n:,} splats (SH 0)")
    print(row("splat-transform .sog", f"{their_size:,} bytes", f"{their_seconds:.1f} s (process, -g cpu)"))
    print(row("splatconv .sog", f"{our_size:,} bytes", f"{our_seconds:.1f} s (process); "
              f"{our_size / their_size:.3f} x splat-transform's"))
    for key, what in (("st_reads_st", "splat-transform reads its own"), ("st_reads_ours", "splat-transform reads ours"),
                      ("we_read_st", "splatconv reads splat-transform's"), ("we_read_ours", "splatconv reads ours")):
        print(row(what, f"{counts[key]:,} splats", f"PSNR {psnr[key]:.2f} dB against the baked PLY"))
    checks = {"splat-transform reads every splat of ours": counts["st_reads_ours"] == n,
              "ours drawn within 0.5 dB of its own": psnr["st_reads_ours"] >= psnr["st_reads_st"] - 0.5,
              "ours at most 1.1 x its size": our_size <= 1.1 * their_size,
              "splatconv reads every splat of its .sog": counts["we_read_st"] == n,
              "splatconv reads its .sog as it does (0.5 dB)": abs(psnr["we_read_st"] - psnr["st_reads_st"]) <= 0.5}
    for what, ok in checks.items():
        print(row(what, "yes" if ok else "NO"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--sh3", action="store_true", help="also time a scene with SH degree 3 bands")
    parser.add_argument("--keep", help="work in this folder and keep it")
    args = parser.parse_args()
    print(machine_line(load=True))
    with work_folder(args.keep, prefix="splatconv-bench-sog-") as folder:
        speed(folder, args.splats, 0)
        if args.sh3:
            speed(folder, args.splats, 3)
        peers(folder)


if __name__ == "__main__":
    main()
