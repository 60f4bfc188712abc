"""Benchmark bake, the static writers and merge against a plain conversion.

On a synthetic Spacetime Gaussians lite PLY (1,000,000 splats by default, made
as ``bench_convert.py`` makes its input), in process, median of several runs,
warm page cache, each output replacing the previous run's:

* plain conversion PLY -> .splatv (the yardstick);
* ``bake`` alone (the op: positions, rotations and opacities at t, hidden
  splats removed), and read + bake + write a 3DGS PLY / a ``.splat`` (what
  ``splatconv bake INPUT OUT --time 0.5`` does);
* ``merge`` of the input with itself to ``.splatv`` (read twice, compose, write).

Prints seconds and each figure over the plain conversion. A report, not a test:
the exit status is 0 whatever the figures. The machine this runs on may be
shared: figures are medians and still noisy.

Run::

    python bench/bench_bake.py [--splats N] [--repeat R]
"""

from __future__ import annotations

import argparse
import os
import sys

import splatconv
from splatconv import io
from splatconv.ops.bake import bake
from splatconv.ops.merge import overlay

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _harness import median_seconds, work_folder  # noqa: E402
from bench_convert import make_ply  # noqa: E402  (the same synthetic input)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--splats", type=int, default=1_000_000, help="splats in the input (default 1,000,000)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure (median; default 3)")
    args = ap.parse_args()
    with work_folder(prefix="splatconv-bench-bake-") as work:
        src = os.path.join(work, "input.ply")
        size = make_ply(src, args.splats)
        print(f"input: {args.splats:,} splats, {size / 1e6:.1f} MB lite PLY; median of {args.repeat} runs")
        out = {suffix: os.path.join(work, "out" + suffix) for suffix in (".splatv", ".ply", ".splat")}
        splatconv.convert(src, out[".splatv"], force=True)  # warm the page cache and the code
        plain = median_seconds(lambda: splatconv.convert(src, out[".splatv"], force=True), args.repeat)
        scene = io.read(src)
        baked_count = bake(scene, 0.5)[0].count
        rows = [("plain conversion PLY -> .splatv", plain)]
        rows.append(("bake at t=0.5 (the op alone)", median_seconds(lambda: bake(io.read(src), 0.5), args.repeat)))
        for suffix in (".ply", ".splat"):
            def run(suffix=suffix):
                io.write(bake(io.read(src), 0.5)[0], out[suffix], force=True)
            rows.append((f"read + bake + write {suffix} ({'3DGS' if suffix == '.ply' else 'antimatter15'})",
                         median_seconds(run, args.repeat)))

        def merge_self():
            merged, _ = overlay([io.read(src), io.read(src)])
            io.write(merged, out[".splatv"], force=True)

        rows.append((f"merge input + input -> .splatv ({2 * args.splats:,} splats)",
                     median_seconds(merge_self, args.repeat)))
        print(f"baked: {baked_count:,} of {args.splats:,} splats visible at t=0.5")
        for label, seconds in rows:
            print(f"  {label:<48} {seconds:7.3f} s  {seconds / plain:5.2f}x plain conversion")


if __name__ == "__main__":
    main()
