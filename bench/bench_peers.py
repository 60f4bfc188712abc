"""Static formats against PlayCanvas splat-transform's own files of the same bake: counts, sizes, fidelity.

Usage: python bench/bench_peers.py [SCENE.splatv] [--time T] [--formats spz,sog,compressed.ply]

Bakes SCENE (default ``../shared/real/yellow_clip3.splatv``) at T (default 0.5) to a 3DGS PLY,
then, for each static format both tools write, makes splatconv's file and splat-transform's file
of that PLY and prints:

* each file's size and the ratio ours / theirs (issue 25 asks for at most 1.1);
* the splats splat-transform reads back from ours (it must read every one) and that we read back
  from theirs;
* how faithfully each reading draws against the baked PLY: the worst frame's PSNR over the views a
  ``.splatvq`` is proved by (``render.proof.proof_views``: the scene's cameras, views near them,
  splaTV's opening view), as the viewer draws them. ``st(ours)`` must be within 0.5 dB of
  ``st(theirs)`` (splat-transform reading its own file), and ``we(theirs)`` within 0.5 dB of it.

The viewer's maths draws the degree-0 colour only, so the bake is compared twice: as it is, and
with SH bands of degree 3 added (seeded random coefficients), whose fidelity is printed as the RMS
difference of the f_rest columns against the PLY's ("dropped" where a reading has none).

splat-transform is found as ``$SPLAT_TRANSFORM`` or ``/tmp/st/node_modules/.bin/splat-transform``;
without it (or without the scene) the bench says so and exits 0.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from splatconv import io, model
from splatconv.render import proof

HERE = Path(__file__).resolve().parent
DEFAULT_SCENE = HERE.parent.parent / "shared" / "real" / "yellow_clip3.splatv"
FORMATS = ("spz", "sog", "compressed.ply")
#: PSNR a reading may lose against splat-transform's reading of its own file (issue 25).
SLACK_DB = 0.5
#: Largest size of ours against theirs (issue 25).
SIZE_RATIO = 1.1


def peer() -> str | None:
    found = os.environ.get("SPLAT_TRANSFORM") or "/tmp/st/node_modules/.bin/splat-transform"
    return found if Path(found).exists() else shutil.which("splat-transform")


def run(*args) -> float:
    start = time.perf_counter()
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"{' '.join(map(str, args))} failed:\n{done.stdout}{done.stderr}")
    return time.perf_counter() - start


def sh_rms(scene, reference) -> str:
    rest = [k for k in model.SH_REST if k in reference.columns]
    if not rest:
        return "-"
    if not all(k in scene.columns for k in rest) or scene.count != reference.count:
        return "dropped" if not all(k in scene.columns for k in rest) else "reordered"
    a = np.stack([scene.columns[k] for k in rest], axis=1).astype(np.float64)
    b = np.stack([reference.columns[k] for k in rest], axis=1).astype(np.float64)
    return f"{np.sqrt(np.mean((a - b) ** 2)):.4f}"


def compare(tool, prover, tmp: Path, baked: Path, reference, suffix: str, label: str) -> list:
    """Ours and splat-transform's files of ``baked`` as ``suffix``, read both ways: the checks missed."""
    failures = []
    ours, theirs = tmp / f"{baked.stem}.ours.{suffix}", tmp / f"{baked.stem}.theirs.{suffix}"
    t_ours = run(sys.executable, "-m", "splatconv", "convert", baked, ours, "--quiet")
    t_theirs = run(tool, "-q", "-w", *(("-g", "cpu") if suffix == "sog" else ()), baked, theirs)
    readings = {}
    for name, path in (("ours", ours), ("theirs", theirs)):
        back = tmp / f"{baked.stem}.st_{name}.{suffix}.ply"
        run(tool, "-q", "-w", path, back)
        readings[f"st({name})"] = io.read(back)
        readings[f"we({name})"] = io.read(path)
    ratio = ours.stat().st_size / theirs.stat().st_size
    print(f"\n.{suffix} of {label}: ours {ours.stat().st_size:,} B in {t_ours:.1f} s, theirs "
          f"{theirs.stat().st_size:,} B in {t_theirs:.1f} s: size ratio {ratio:.3f}")
    psnr = {}
    for name, scene in readings.items():
        got = prover.prove(scene)
        psnr[name] = got.worst
        print(f"  {name:<11} {scene.count:>9,} splats  degree {scene.sh_degree}  worst {got.worst:6.2f} dB  "
              f"mean {got.mean:6.2f} dB  SH rms {sh_rms(scene, reference)}")
    checks = {
        "splat-transform reads every splat of ours": readings["st(ours)"].count == reference.count,
        "we read every splat of theirs": readings["we(theirs)"].count == readings["st(theirs)"].count,
        "SH degree kept as theirs keeps it": readings["st(ours)"].sh_degree == readings["st(theirs)"].sh_degree,
        f"st(ours) within {SLACK_DB} dB of st(theirs)": psnr["st(ours)"] >= psnr["st(theirs)"] - SLACK_DB,
        f"we(theirs) within {SLACK_DB} dB of st(theirs)": psnr["we(theirs)"] >= psnr["st(theirs)"] - SLACK_DB,
        f"size at most {SIZE_RATIO}x theirs": ratio <= SIZE_RATIO,
    }
    for what, ok in checks.items():
        print(f"  {'ok  ' if ok else 'FAIL'} {what}")
        if not ok:
            failures.append(f".{suffix} of {label}: {what}")
    return failures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE))
    parser.add_argument("--time", type=float, default=0.5)
    parser.add_argument("--formats", default=",".join(FORMATS))
    args = parser.parse_args()
    tool = peer()
    if tool is None:
        print("splat-transform not found ($SPLAT_TRANSFORM or /tmp/st): nothing to compare")
        return 0
    if not Path(args.scene).exists():
        print(f"{args.scene} is absent (the real scenes live in ../shared/real): nothing to compare")
        return 0
    done = subprocess.run([tool, "--version"], capture_output=True, text=True)
    version = (done.stdout + done.stderr).strip()
    print(f"peer: {version}; scene: {args.scene} at t={args.time:g}")
    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        baked = tmp / "baked.ply"
        run(sys.executable, "-m", "splatconv", "bake", args.scene, baked, "--time", args.time, "--quiet")
        reference = io.read(baked)
        reference.cameras = io.read(args.scene).cameras
        views = proof.proof_views(reference)
        print(f"baked: {reference.count:,} splats, {baked.stat().st_size:,} bytes; "
              f"{len(views)} views")
        rng = np.random.default_rng(3)
        sh = {k: rng.normal(0.0, 0.1, reference.count).astype(np.float32) for k in model.sh_names(3)}
        with_sh = tmp / "baked_sh3.ply"
        io.write(dataclasses.replace(reference, columns={**reference.columns, **sh}), with_sh)
        with proof.Prover(reference, views, (args.time,)) as prover:
            for label, source in (("the bake", baked), ("the bake with SH degree 3", with_sh)):
                expected = io.read(source)
                for suffix in args.formats.split(","):
                    failures += compare(tool, prover, tmp, source, expected, suffix, label)
    print("\nall checks met" if not failures else "\nmissed: " + "; ".join(failures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
