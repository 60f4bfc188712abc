"""Benchmark bake against a plain conversion of the same ``.splatv``, side by side.

On a synthetic 4D scene (1,000,000 splats by default: the lite PLY ``bench_convert.py``
makes, converted once to ``.splatv``), in process, median of several runs, warm
page cache, each output replacing the previous run's:

* the yardsticks: ``convert X.splatv OUT.ply`` and ``convert X.splatv OUT.splatv``
  (:func:`splatconv.jobs.convert.convert`: read, write). ``convert X.splatv
  OUT.splat`` is refused for a scene that moves (a ``.splat`` is static: bake a
  moment first), so both bakes are measured against the conversion to PLY;
* ``bake`` alone (the op: positions, rotations and opacities at t, undrawn
  splats left out), and ``bake X.splatv OUT.ply`` / ``OUT.splat --time 0.5``
  (:func:`splatconv.jobs.bake.bake`: read, bake, write), each over the
  conversion to PLY;
* ``merge`` of the input with itself to ``.splatv`` (read twice, compose, write).

Prints seconds and each figure over the conversion to PLY. A report, not a test:
the exit status is 0 whatever the figures. The machine this runs on may be
shared: figures are medians and still noisy; the ratios, measured in one run,
are steadier than the seconds.

Run::

    python bench/bench_bake.py [--splats N] [--repeat R]
"""

from __future__ import annotations

import argparse
import os
import sys

import splatconv
from splatconv import io
from splatconv.jobs.bake import bake as bake_job
from splatconv.jobs.convert import convert
from splatconv.ops.bake import bake
from splatconv.ops.merge import overlay

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _harness import machine_line, median_seconds, work_folder  # noqa: E402
from bench_convert import make_ply  # noqa: E402  (the same synthetic input)

#: Target: bake to a PLY or a .splat in at most this many times the conversion to PLY.
TARGET_RATIO = 2.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--splats", type=int, default=1_000_000, help="splats in the input (default 1,000,000)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure (median; default 3)")
    args = ap.parse_args()
    with work_folder(prefix="splatconv-bench-bake-") as work:
        ply = os.path.join(work, "input.ply")
        make_ply(ply, args.splats)
        src = os.path.join(work, "input.splatv")
        splatconv.convert(ply, src)
        os.remove(ply)
        print(f"input: {args.splats:,} splats, {os.path.getsize(src) / 1e6:.1f} MB .splatv; median of "
              f"{args.repeat} runs; {machine_line(load=True)}")
        out = {suffix: os.path.join(work, "out" + suffix) for suffix in (".splatv", ".ply", ".splat")}
        convert(src, out[".ply"], force=True)  # warm the page cache and the code
        yardstick = median_seconds(lambda: convert(src, out[".ply"], force=True), args.repeat)
        rows = [("convert X.splatv OUT.ply (the yardstick)", yardstick),
                ("convert X.splatv OUT.splatv",
                 median_seconds(lambda: convert(src, out[".splatv"], force=True), args.repeat))]
        scene = io.read(src)
        baked_count = bake(scene, 0.5)[0].count
        rows.append(("bake at t=0.5 (the op alone)", median_seconds(lambda: bake(scene, 0.5), args.repeat)))
        del scene
        for suffix in (".ply", ".splat"):
            rows.append((f"bake X.splatv OUT{suffix} --time 0.5",
                         median_seconds(lambda suffix=suffix: bake_job(src, out[suffix], time=0.5, force=True),
                                        args.repeat)))

        def merge_self():
            merged, _ = overlay([io.read(src), io.read(src)])
            io.write(merged, out[".splatv"], force=True)

        rows.append((f"merge X + X -> .splatv ({2 * args.splats:,} splats)", median_seconds(merge_self, args.repeat)))
        print(f"baked: {baked_count:,} of {args.splats:,} splats drawn at t=0.5")
        for label, seconds in rows:
            print(f"  {label:<44} {seconds:7.3f} s  {seconds / yardstick:5.2f}x convert X.splatv OUT.ply")
        print(f"target: bake to .ply and to .splat at most {TARGET_RATIO:g}x convert X.splatv OUT.ply")


if __name__ == "__main__":
    main()
