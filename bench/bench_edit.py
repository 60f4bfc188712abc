"""Benchmark ``convert`` with edits against a plain conversion of the same scene.

The issue's target: a 1M-splat scene filtered, transformed and written within
1.5x the time of a plain conversion. Input: the synthetic Spacetime Gaussians
lite PLY of ``bench_convert.py`` (1,000,000 splats, 128 MB by default) with
some NaN and infinite values planted, as trained scenes carry them (200 NaN
positions, 50 infinite motion values, 20 NaN opacities).

Conversions, each in a fresh process (started by a small launcher, so the peak
RSS is the conversion's own), runs of the configurations interleaved so that
drift in the machine's load hits all of them alike, medians of ``--repeat``:

* plain: PLY -> .splatv;
* filter + transform: ``--drop-nonfinite --crop -6,-6,-6,6,6,6 --min-opacity 0.02
  --rotate x:90,y:30 --translate 1,2,3 --scale 1.5`` -> .splatv (the filters
  remove about 3% of the splats, as clean-up of a trained scene does: a filter
  that removed much would flatter the figures, the writer then having less to do);
* every edit: the same plus ``--trim 0.1,0.9 --max-splats 800000``.

For each: the conversion's wall seconds in process (modules loaded before the
clock starts), its CPU seconds (``time.process_time``: all threads; steadier
than wall seconds on a shared machine), the seconds of the edit step alone,
the whole command's wall seconds and peak RSS; then the ratios to the plain
conversion. A last block runs ``splatconv convert`` itself (console script,
interpreter start included) plain and with the filter + transform options.
The exit status is 0 whatever the figures; it is a report, not a test.

Run::

    python bench/bench_edit.py [--splats N] [--repeat R] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

import splatconv
from _harness import CLI, PYTHON, bench_fields, machine_line, medians, row, run_fresh, work_folder
from bench_convert import make_ply

#: The target: edited conversion seconds over plain conversion seconds.
TARGET_RATIO = 1.5

#: Child: convert argv[1] -> argv[2] with the edit plan argv[3] (JSON, or "-" for
#: none); print wall and CPU seconds of the conversion and of the edit step.
CHILD = """\
import json, sys, time
import splatconv, splatconv.formats, splatconv.formats.splatv, splatconv.formats.ply, splatconv.ops
from splatconv.ops import EditPlan, apply_edits, make_transform
spec = None if sys.argv[3] == "-" else json.loads(sys.argv[3])
edit, spent = None, [0.0, 0.0]
if spec is not None:
    tf = spec.pop("transform", None)
    if spec.get("crop"):
        spec["crop"] = (spec["crop"][:3], spec["crop"][3:])
    plan = EditPlan(transform=make_transform(**tf) if tf else None, **spec)
    def edit(scene):
        w, c = time.perf_counter(), time.process_time()
        out, _ = apply_edits(scene, plan)
        spent[0], spent[1] = time.perf_counter() - w, time.process_time() - c
        return out
w, c = time.perf_counter(), time.process_time()
_, report = splatconv.convert(sys.argv[1], sys.argv[2], force=True, edit=edit)
print("BENCH", time.perf_counter() - w, time.process_time() - c, spent[0], spent[1], report.count)
"""

FILTER_TRANSFORM = {"drop_nonfinite": True, "crop": [-6.0, -6.0, -6.0, 6.0, 6.0, 6.0], "min_opacity": 0.02,
                    "transform": {"translate": [1.0, 2.0, 3.0], "rotate": "x:90,y:30", "scale": 1.5}}
EVERYTHING = dict(FILTER_TRANSFORM, trim=[0.1, 0.9], max_splats=800_000)
CLI_EDITS = ["--drop-nonfinite", "--crop", "-6,-6,-6,6,6,6", "--min-opacity", "0.02", "--rotate", "x:90,y:30",
             "--translate", "1,2,3", "--scale", "1.5"]


def plant_nonfinite(path: str, n: int) -> None:
    """Put NaN and infinite values into the generated PLY, in place."""
    from splatconv.formats.ply import LITE_DTYPE, header_bytes

    rows = np.memmap(path, dtype=LITE_DTYPE, mode="r+", offset=len(header_bytes(n, None)), shape=(n,))
    rng = np.random.default_rng(1)
    rows["x"][rng.choice(n, 200, replace=False)] = np.nan
    rows["motion_4"][rng.choice(n, 50, replace=False)] = np.inf
    rows["opacity"][rng.choice(n, 20, replace=False)] = np.nan
    rows.flush()
    del rows


def launch(argv: list) -> dict:
    """Run ``argv`` in a fresh process through :func:`_harness.run_fresh`'s launcher (so the
    peak RSS is the conversion's own); its BENCH line, wall seconds and peak RSS (MB)."""
    r = run_fresh(argv, check=True)
    out = {}
    fields = bench_fields(r["stdout"])
    if "BENCH" in fields:
        wall, cpu, edit_wall, edit_cpu, count = fields["BENCH"]
        out.update(seconds=float(wall), cpu=float(cpu), edit=float(edit_wall), edit_cpu=float(edit_cpu),
                   count=int(count))
    out.update(code=r["code"], wall=r["wall"], rss_mb=r["rss_mb"])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--splats", type=int, default=1_000_000, help="splats in the input (default 1,000,000)")
    ap.add_argument("--repeat", type=int, default=5, help="runs per figure (median; default 5)")
    ap.add_argument("--keep", metavar="DIR", help="work in DIR and leave the files there")
    args = ap.parse_args(argv)
    with work_folder(args.keep, "splatconv-bench-edit-") as work:
        return run(args, work)


def run(args, work: str) -> int:
    n = args.splats
    src = os.path.join(work, "input.ply")
    print(f"splatconv {splatconv.__version__} edit benchmark -- {machine_line()}")
    t = time.perf_counter()
    size = make_ply(src, n)
    plant_nonfinite(src, n)
    print(f"input: {n:,} splats, {size / 1e6:.1f} MB lite PLY with 270 NaN/inf values "
          f"(made in {time.perf_counter() - t:.1f} s)")
    print(f"fresh process per run, configurations interleaved, median of {args.repeat}; load average now "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    print()

    configs = {"plain": None, "filter + transform": FILTER_TRANSFORM, "every edit": EVERYTHING}
    runs = {name: [] for name in configs}
    for _ in range(args.repeat):
        for name, spec in configs.items():
            dst = os.path.join(work, f"{name.replace(' ', '').replace('+', '_')}.splatv")
            runs[name].append(launch([PYTHON, "-c", CHILD, src, dst, json.dumps(spec) if spec else "-"]))
    result = {name: medians(r) for name, r in runs.items()}
    plain = result["plain"]
    for name, r in result.items():
        print(f"PLY -> .splatv, {name}: {r['count']:,} splats written")
        print(row("conversion, in process (wall)", f"{r['seconds']:.3f} s",
                  "" if r is plain else f"{r['seconds'] / plain['seconds']:.2f}x plain"))
        print(row("conversion, in process (CPU, all threads)", f"{r['cpu']:.3f} s",
                  "" if r is plain else f"{r['cpu'] / plain['cpu']:.2f}x plain"))
        if r is not plain:
            print(row("  of which the edits (wall / CPU)", f"{r['edit']:.3f} s", f"{r['edit_cpu']:.3f} s CPU"))
        print(row("wall, python -c (incl. interpreter start)", f"{r['wall']:.3f} s"))
        print(row("peak RSS", f"{r['rss_mb']:.0f} MB"))
    print()

    cli = {"plain": [], "filter + transform": []}
    for _ in range(args.repeat):
        cli["plain"].append(launch([CLI, "convert", src, os.path.join(work, "cli.splatv"), "--force"]))
        cli["filter + transform"].append(launch([CLI, "convert", src, os.path.join(work, "cli-edit.splatv"),
                                                 "--force", *CLI_EDITS]))
    cli_plain = statistics.median(r["wall"] for r in cli["plain"])
    cli_edit = statistics.median(r["wall"] for r in cli["filter + transform"])
    print("splatconv convert (console script, interpreter start included)")
    print(row("plain", f"{cli_plain:.3f} s"))
    print(row("filter + transform options", f"{cli_edit:.3f} s", f"{cli_edit / cli_plain:.2f}x plain"))
    print()

    ft = result["filter + transform"]
    print(f"target: filtered, transformed and written within {TARGET_RATIO}x a plain conversion")
    for label, ratio in (("in process, wall", ft["seconds"] / plain["seconds"]),
                         ("in process, CPU", ft["cpu"] / plain["cpu"]),
                         ("command, wall", cli_edit / cli_plain)):
        print(row(label, f"{ratio:.2f}x", "PASS" if ratio <= TARGET_RATIO else "FAIL"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
