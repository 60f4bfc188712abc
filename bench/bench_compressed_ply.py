"""PlayCanvas ``compressed.ply``: splatconv's encode and decode beside gsply's, and the peer check with
splat-transform on a real scene.

Usage: python bench/bench_compressed_ply.py [--splats 1000000] [--real DIR] [--keep DIR]

1. Timing: a random static scene of SPLATS splats at SH degree 0 and 3, written as a compressed PLY
   (``io.write``: Morton order, encode, write) and read back (``io.read``), best of three; beside
   gsply's ``compress_to_bytes`` + write and ``read_compressed`` of the same arrays, in one run, as
   ratios (gsply runs in its own interpreter, ``GSPLY_PYTHON``, default ``/tmp/libvenv/bin/python``,
   after a warm-up call that compiles its Numba kernels).
2. Peer check, on ``yellow_clip3.splatv`` from DIR (default ``../shared/real``): bake t = 0.5 to a
   plain PLY; splat-transform (``SPLAT_TRANSFORM``, default ``/tmp/st/node_modules/.bin/splat-transform``)
   and splatconv each write its compressed PLY; sizes; each file read back by both tools (splat-transform
   to a plain PLY); splat counts; and each reading drawn against the baked PLY from the views
   ``convert --min-psnr`` proves by (``render/proof.py``): worst and mean PSNR.

Done means: splat-transform reads splatconv's file with every splat and draws it within 0.5 dB of
its own file at no more than 1.1x its size; splatconv reads splat-transform's with every splat at
the same fidelity. Each absent peer or scene is said plainly and its part skipped.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from splatconv import io, model
from splatconv.model import Scene

from _harness import best_seconds as best

ROOT = Path(__file__).resolve().parent.parent
REAL = ROOT.parent / "shared" / "real"
SCENE = "yellow_clip3.splatv"
SPLAT_TRANSFORM = os.environ.get("SPLAT_TRANSFORM", "/tmp/st/node_modules/.bin/splat-transform")
GSPLY_PYTHON = os.environ.get("GSPLY_PYTHON", "/tmp/libvenv/bin/python")

#: gsply's side of the timing, run in its interpreter: arrays from an .npz, best of three.
GSPLY_SCRIPT = r"""
import json, sys, time
import numpy as np
import gsply
from gsply.reader import read_compressed
from gsply.writer import compress_to_bytes
d = np.load(sys.argv[1])
shn = d["shN"] if d["shN"].size else None
args = (d["means"], d["scales"], d["quats"], d["opacities"], d["sh0"], shn)
small = [a[:1024] if a is not None else None for a in args]
compress_to_bytes(*small)  # compiles the Numba kernels
def best(fn):
    times = []
    for _ in range(3):
        t = time.perf_counter(); fn(); times.append(time.perf_counter() - t)
    return min(times)
out = sys.argv[2]
def encode():
    with open(out, "wb") as f:
        f.write(compress_to_bytes(*args))
enc = best(encode)
read_compressed(out)
dec = best(lambda: read_compressed(out))
print(json.dumps({"encode": enc, "decode": dec, "bytes": len(open(out, "rb").read()),
                  "version": getattr(gsply, "__version__", "?")}))
"""


def random_scene(n: int, degree: int) -> Scene:
    rng = np.random.default_rng(7)
    cols = {name: rng.uniform(-3, 3, n).astype(np.float32) for name in model.POSITION}
    cols.update({name: rng.uniform(0, 1, n).astype(np.float32) for name in model.COLOR})
    cols["opacity"] = rng.normal(0, 2, n).astype(np.float32)
    cols.update({name: rng.uniform(-6, -2, n).astype(np.float32) for name in model.SCALE})
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    cols.update({name: q[:, i].astype(np.float32) for i, name in enumerate(model.ROTATION)})
    cols.update({name: rng.normal(0, 0.2, n).astype(np.float32) for name in model.sh_names(degree)})
    cols.update(model.static_columns(n))
    return Scene(columns=cols, variant=model.VARIANT_3DGS)


def gsply_arrays(scene: Scene, path: Path) -> None:
    """The scene as gsply takes it: means, log scales, quaternions (w x y z), logit opacities, f_dc, shN."""
    c = scene.columns
    sh0 = (np.stack([c[n] for n in model.COLOR], axis=1) - 0.5) / 0.28209479177387814
    k = model.SH_COEFFS[scene.sh_degree]
    shn = np.stack([c[n] for n in model.sh_names(scene.sh_degree)], axis=1).reshape(-1, 3, k).transpose(0, 2, 1) \
        if k else np.zeros((0,), np.float32)
    np.savez(path, means=np.stack([c[n] for n in model.POSITION], axis=1),
             scales=np.stack([c[n] for n in model.SCALE], axis=1),
             quats=np.stack([c[n] for n in model.ROTATION], axis=1), opacities=c["opacity"],
             sh0=sh0.astype(np.float32), shN=np.ascontiguousarray(shn, dtype=np.float32))


def timing(n: int, tmp: Path) -> None:
    peer = Path(GSPLY_PYTHON).is_file()
    if not peer:
        print(f"gsply: absent ({GSPLY_PYTHON} not found); splatconv's times alone")
    for degree in (0, 3):
        scene = random_scene(n, degree)
        out = tmp / f"sh{degree}.compressed.ply"
        enc = best(lambda: io.write(scene, out, force=True))
        dec = best(lambda: io.read(out))
        line = (f"{n:,} SH{degree} splats: splatconv encode {enc:.2f} s, decode {dec:.2f} s, "
                f"{out.stat().st_size:,} bytes")
        if peer:
            arrays = tmp / f"sh{degree}.npz"
            gsply_arrays(scene, arrays)
            r = subprocess.run([GSPLY_PYTHON, "-c", GSPLY_SCRIPT, str(arrays), str(tmp / "gsply.compressed.ply")],
                               capture_output=True, text=True)
            if r.returncode:
                line += f"; gsply failed: {r.stderr.strip().splitlines()[-1:]}"
            else:
                g = json.loads(r.stdout.strip().splitlines()[-1])
                line += (f"; gsply {g['version']} encode {g['encode']:.2f} s, decode {g['decode']:.2f} s, "
                         f"{g['bytes']:,} bytes; ratio (splatconv / gsply) encode {enc / g['encode']:.2f}x, "
                         f"decode {dec / g['decode']:.2f}x")
        print(line, flush=True)


def _st(*args) -> None:
    r = subprocess.run([SPLAT_TRANSFORM, "-q", "-w", *map(str, args)], capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"splat-transform {' '.join(map(str, args))} failed: {r.stderr.strip()[-400:]}")


def _splatconv(*args) -> None:
    r = subprocess.run([sys.executable, "-m", "splatconv", *map(str, args), "--force"], capture_output=True,
                       text=True)
    if r.returncode:
        raise SystemExit(f"splatconv {' '.join(map(str, args))} failed: {r.stderr.strip()[-400:]}")


def peer_check(folder: Path, tmp: Path) -> None:
    source = folder / SCENE
    if not source.is_file():
        print(f"peer check: {source} is absent ({folder} is not part of the repository); skipped")
        return
    if not Path(SPLAT_TRANSFORM).is_file():
        print(f"peer check: splat-transform absent ({SPLAT_TRANSFORM} not found); skipped")
        return
    from splatconv.render.proof import Prover, proof_plan

    baked, st_file, ours = tmp / "c.ply", tmp / "st.compressed.ply", tmp / "ours.compressed.ply"
    _splatconv("bake", source, baked, "--time", "0.5")
    _st(baked, st_file)
    _splatconv("convert", baked, ours)
    st_of_ours, st_of_st = tmp / "st_of_ours.ply", tmp / "st_of_st.ply"
    _st(ours, st_of_ours)
    _st(st_file, st_of_st)
    base = io.read(baked)
    print(f"\npeer check on {SCENE} baked at t = 0.5: {base.count:,} splats, SH degree {base.sh_degree}")
    size_st, size_ours = st_file.stat().st_size, ours.stat().st_size
    print(f"  sizes: splat-transform {size_st:,} bytes, splatconv {size_ours:,} bytes "
          f"({size_ours / size_st:.3f}x)")
    readings = (("splat-transform's file read by splat-transform", st_of_st),
                ("splat-transform's file read by splatconv", st_file),
                ("splatconv's file read by splat-transform", st_of_ours),
                ("splatconv's file read by splatconv", ours))
    views, times = proof_plan(base)
    results = {}
    with Prover(base, views, times) as prover:
        for label, path in readings:
            scene = io.read(path)
            proof = prover.prove(scene)
            results[label] = (scene.count, proof)
            print(f"  {label}: {scene.count:,} splats; worst {proof.worst:.2f} dB ({proof.where}), "
                  f"mean {proof.mean:.2f} dB over {proof.frames} frames")
    ref = results[readings[0][0]][1]
    n_st_ours, p_st_ours = results[readings[2][0]]
    n_ours_st, p_ours_st = results[readings[1][0]]
    checks = [
        ("splat-transform reads every splat of splatconv's file", n_st_ours == base.count),
        (f"it draws within 0.5 dB of splat-transform's own file (worst {p_st_ours.worst - ref.worst:+.2f} dB, "
         f"mean {p_st_ours.mean - ref.mean:+.2f} dB)", min(p_st_ours.worst - ref.worst, p_st_ours.mean - ref.mean)
         >= -0.5),
        (f"at no more than 1.1x its size ({size_ours / size_st:.3f}x)", size_ours <= 1.1 * size_st),
        ("splatconv reads every splat of splat-transform's file", n_ours_st == base.count),
        (f"at the same fidelity as splat-transform reads it (worst {p_ours_st.worst - ref.worst:+.2f} dB, "
         f"mean {p_ours_st.mean - ref.mean:+.2f} dB)",
         abs(p_ours_st.worst - ref.worst) <= 0.05 and abs(p_ours_st.mean - ref.mean) <= 0.05),
    ]
    for text, ok in checks:
        print(f"  {'PASS' if ok else 'FAIL'}: {text}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--real", default=str(REAL))
    parser.add_argument("--keep", help="keep the files in this folder")
    parser.add_argument("--no-timing", action="store_true", help="the peer check only")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        tmp = Path(args.keep or scratch)
        tmp.mkdir(parents=True, exist_ok=True)
        if not args.no_timing:
            timing(args.splats, tmp)
        peer_check(Path(args.real), tmp)


if __name__ == "__main__":
    main()
