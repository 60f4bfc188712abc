"""Benchmark splatconv's conversions against the machine's I/O floor.

What it measures, on a synthetic Spacetime Gaussians lite PLY (32 float32
properties a row, 128 bytes a splat; 1,000,000 splats = 128 MB by default):

* the I/O floor, as the issue that set the target defines it: "the time to
  merely read that input and write an output of the same size" -- reading the
  whole input into a preallocated buffer plus writing a file of the input's size
  from a preallocated buffer, warm (page cache), median of several runs. Also
  the tighter floor with the write cut to the ``.splatv`` output's size (half
  the input), against which the ratio is shown too;
* PLY -> .splatv (default, accurate mode): in-process conversion seconds
  (median; the library's modules are loaded before the clock starts, as numpy
  is before the floor's), the seconds that first use spends loading them,
  whole-command wall seconds including interpreter start (``python -c`` and the
  ``splatconv convert`` console script), peak RSS of the converting process, and
  the ratios conversion / I/O floor;
* PLY -> .splatv with ``compat="splatv-js"``, PLY -> .splatv.zst (zstd level 3,
  to show the compressed output streams), and .splatv -> PLY, the same way.

Like the floor's writes, every conversion replaces the previous run's output
(atomically, through a temporary file), so both pay for the page cache the
replaced file frees. Every conversion runs in a fresh child process so that its
peak RSS (from ``os.wait4``) is that conversion's alone. A final block compares
the default mode against the targets (at most 2.5x the I/O floor, at most 350 MB
peak RSS). The exit status is 0 whatever the figures; it is a report, not a test.

Run::

    python bench/bench_convert.py [--splats N] [--keep DIR] [--repeat R]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

import splatconv
from splatconv.formats.ply import LITE_DTYPE, header_bytes

from _harness import CLI, PYTHON, bench_fields, machine_line, medians, row, run_fresh, work_folder

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from tests.scenes import CONVERT, draw_columns  # noqa: E402  (the scene factory the tests use)

#: Conversion target: seconds of the default conversion over the I/O floor.
TARGET_RATIO = 2.5
#: Memory target: peak RSS of the converting process, MB (10^6 bytes).
TARGET_RSS_MB = 350.0

#: Bytes of .splatv header assumed for the floor's output file.
SPLATV_HEADER_BYTES = 400

#: Child snippet: convert argv[1] -> argv[2] (compat argv[3] or "-", zstd level
#: argv[4] or "-") and print the seconds of loading the library's modules, then of
#: the conversion.
CHILD = """\
import sys, time, splatconv
t = time.perf_counter()
import splatconv.formats, splatconv.formats.splatv_engine, splatconv.files, splatconv.zstd
print("BENCH_LOAD", time.perf_counter() - t)
compat = None if sys.argv[3] == "-" else sys.argv[3]
level = None if sys.argv[4] == "-" else int(sys.argv[4])
t = time.perf_counter()
splatconv.convert(sys.argv[1], sys.argv[2], compat=compat, force=True, zstd_level=level)
print("BENCH_SECONDS", time.perf_counter() - t)
"""


def make_ply(path: str, n: int) -> int:
    """Write a deterministic ``n``-splat lite PLY (:data:`tests.scenes.CONVERT`) to ``path``; return its size."""
    cols = draw_columns(n, 0, CONVERT)
    arr = np.zeros(n, dtype=LITE_DTYPE)  # nx, ny, nz stay 0
    for name, column in cols.items():
        arr[name] = column
    with open(path, "wb") as f:
        f.write(header_bytes(n, None))
        arr.tofile(f)
    return os.path.getsize(path)


def splatv_size(n: int) -> int:
    """Bytes of a .splatv file of ``n`` splats: texture plus an assumed header."""
    return 4096 * (-(-n // 1024)) * 16 + SPLATV_HEADER_BYTES


def time_read(path: str, repeat: int) -> float:
    """Median seconds to read ``path`` whole into a preallocated buffer."""
    buf = bytearray(os.path.getsize(path))
    view = memoryview(buf)
    times = []
    for _ in range(repeat + 1):  # the first run only warms the page cache
        t = time.perf_counter()
        with open(path, "rb", buffering=0) as f:
            got = 0
            while got < len(buf):
                k = f.readinto(view[got:])
                if not k:
                    break
                got += k
        times.append(time.perf_counter() - t)
    return statistics.median(times[1:])


def time_write(path: str, size: int, repeat: int) -> float:
    """Median seconds to write ``size`` bytes from a preallocated buffer to a new file.

    Like splatconv's atomic writer, each run writes a fresh file beside ``path``
    and renames it over ``path``.
    """
    buf = np.ones(size, dtype=np.uint8)  # touched, so no page faults are timed
    times = []
    for i in range(repeat):
        tmp = f"{path}.{i}.part"
        t = time.perf_counter()
        with open(tmp, "wb", buffering=0) as f:
            f.write(memoryview(buf))
        os.replace(tmp, path)
        times.append(time.perf_counter() - t)
    os.unlink(path)
    return statistics.median(times)


def run_child(argv: list) -> dict:
    """Run ``argv`` in a fresh process (:func:`_harness.run_fresh`, through its launcher, so the
    peak RSS is the command's own and not this process's, which holds the generated input);
    return its wall seconds, peak RSS (MB) and the seconds it printed (``None`` where it printed none)."""
    r = run_fresh(argv, check=True)
    fields = bench_fields(r["stdout"])
    return {"seconds": float(fields["BENCH_SECONDS"][0]) if "BENCH_SECONDS" in fields else None,
            "load": float(fields["BENCH_LOAD"][0]) if "BENCH_LOAD" in fields else None,
            "code": r["code"], "wall": r["wall"], "rss_mb": r["rss_mb"]}


def measure(src: str, dst: str, compat: str | None, repeat: int, cli: bool, level: int | None = None) -> dict:
    """Convert ``src`` -> ``dst`` ``repeat`` times via ``python -c`` (and the CLI if asked).

    Returns medians of conversion, module-loading and wall seconds and the largest peak RSS.
    """
    args = [PYTHON, "-c", CHILD, src, dst, compat or "-", "-" if level is None else str(level)]
    runs = [run_child(args) for _ in range(repeat)]
    result = medians(runs, ("seconds", "load", "wall"))
    if cli:
        argv = [CLI, "convert", src, dst, "--force"] + (["--compat", compat] if compat else [])
        cli_runs = medians([run_child(argv) for _ in range(repeat)], ("wall",))
        result["cli_wall"] = cli_runs["wall"]
        result["cli_rss_mb"] = cli_runs["rss_mb"]
    return result


def baseline_rss() -> float:
    """Peak RSS (MB) of a child that only imports splatconv and its formats: the fixed cost."""
    return run_child([PYTHON, "-c", "import splatconv.formats.splatv, splatconv.formats.ply"])["rss_mb"]


def main(argv=None) -> int:
    """Parse options, run every measurement and print the report."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--splats", type=int, default=1_000_000, help="splats in the input (default 1,000,000)")
    ap.add_argument("--keep", metavar="DIR", help="work in DIR and leave the files there")
    ap.add_argument("--repeat", type=int, default=3, help="conversion runs per figure (median; default 3)")
    ap.add_argument("--io-repeat", type=int, default=5, help="read/write runs for the floor (median; default 5)")
    args = ap.parse_args(argv)
    with work_folder(args.keep, "splatconv-bench-") as work:
        return run(args, work)


def run(args, work: str) -> int:
    """The benchmark proper, in folder ``work``."""
    n = args.splats
    src = os.path.join(work, "input.ply")
    dst = os.path.join(work, "output.splatv")
    compat_dst = os.path.join(work, "output-compat.splatv")
    back = os.path.join(work, "roundtrip.ply")

    print(f"splatconv {splatconv.__version__} benchmark -- {machine_line()}")
    print(f"work folder: {work}")
    t = time.perf_counter()
    in_bytes = make_ply(src, n)
    print(f"input: {n:,} splats, {in_bytes / 1e6:.1f} MB lite PLY (generated in {time.perf_counter() - t:.1f} s)")
    print()

    out_bytes = splatv_size(n)
    read_s = time_read(src, args.io_repeat)
    write_s = time_write(os.path.join(work, "floor.bin"), in_bytes, args.io_repeat)
    write_out_s = time_write(os.path.join(work, "floor-out.bin"), out_bytes, args.io_repeat)
    floor = read_s + write_s
    tight = read_s + write_out_s
    print(f"I/O floor (warm page cache, median of {args.io_repeat}; each write replaces the last)")
    print(row(f"read {in_bytes / 1e6:.1f} MB (the input)", f"{read_s:.3f} s", f"{in_bytes / read_s / 1e9:.2f} GB/s"))
    print(row(f"write {in_bytes / 1e6:.1f} MB (an output of the same size)", f"{write_s:.3f} s",
              f"{in_bytes / write_s / 1e9:.2f} GB/s"))
    print(row("floor = read + write", f"{floor:.3f} s", "the issue's definition"))
    print(row(f"write {out_bytes / 1e6:.1f} MB (the .splatv's size)", f"{write_out_s:.3f} s",
              f"{out_bytes / write_out_s / 1e9:.2f} GB/s"))
    print(row("tighter floor = read + that write", f"{tight:.3f} s"))
    print()

    base = baseline_rss()
    print(f"conversions (fresh process each, median of {args.repeat}; RSS = largest peak)")
    print(row("baseline RSS: python + import splatconv", f"{base:.0f} MB"))

    default = measure(src, dst, None, args.repeat, cli=True)
    print(f"PLY -> .splatv (default, accurate; output {os.path.getsize(dst) / 1e6:.1f} MB)")
    print(row("conversion, in process", f"{default['seconds']:.3f} s",
              f"{default['seconds'] / floor:.2f}x floor, {default['seconds'] / tight:.2f}x tighter floor"))
    print(row("loading splatconv's modules (first use)", f"{default['load']:.3f} s"))
    print(row("wall, python -c (incl. interpreter start)", f"{default['wall']:.3f} s"))
    print(row("wall, splatconv convert (console script)", f"{default['cli_wall']:.3f} s"))
    print(row("peak RSS, python -c", f"{default['rss_mb']:.0f} MB"))
    print(row("peak RSS, splatconv convert", f"{default['cli_rss_mb']:.0f} MB"))
    print(row("ratio conversion / floor", f"{default['seconds'] / floor:.2f}x"))

    compat = measure(src, compat_dst, "splatv-js", args.repeat, cli=False)
    print("PLY -> .splatv (--compat splatv-js)")
    print(row("conversion, in process", f"{compat['seconds']:.3f} s", f"{compat['seconds'] / floor:.2f}x floor"))
    print(row("wall, python -c", f"{compat['wall']:.3f} s"))
    print(row("peak RSS", f"{compat['rss_mb']:.0f} MB"))

    zst = measure(src, dst + ".zst", None, args.repeat, cli=False, level=3)
    print(f"PLY -> .splatv.zst (zstd level 3, compressed while written; "
          f"output {os.path.getsize(dst + '.zst') / 1e6:.1f} MB)")
    print(row("conversion, in process", f"{zst['seconds']:.3f} s"))
    print(row("peak RSS", f"{zst['rss_mb']:.0f} MB",
              f"{zst['rss_mb'] - default['rss_mb']:+.0f} MB against plain .splatv output"))

    reverse = measure(dst, back, None, args.repeat, cli=False)
    rev_floor_note = f"{os.path.getsize(dst) / 1e6:.1f} MB -> {os.path.getsize(back) / 1e6:.1f} MB"
    print(".splatv -> PLY")
    print(row("conversion, in process", f"{reverse['seconds']:.3f} s", rev_floor_note))
    print(row("wall, python -c", f"{reverse['wall']:.3f} s"))
    print(row("peak RSS", f"{reverse['rss_mb']:.0f} MB"))
    print()

    ratio = default["seconds"] / floor
    rss = max(default["rss_mb"], default["cli_rss_mb"])
    print("targets (PLY -> .splatv, default mode)")
    print(row(f"conversion <= {TARGET_RATIO}x I/O floor", f"{ratio:.2f}x", "PASS" if ratio <= TARGET_RATIO else "FAIL"))
    tight_ratio = default["seconds"] / tight
    print(row(f"  (against the tighter floor, {TARGET_RATIO}x)", f"{tight_ratio:.2f}x",
              "met" if tight_ratio <= TARGET_RATIO else "not met"))
    print(row(f"peak RSS <= {TARGET_RSS_MB:.0f} MB", f"{rss:.0f} MB", "PASS" if rss <= TARGET_RSS_MB else "FAIL"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
