"""Seconds and peak memory of ``splatconv stats`` on a 1,000,000-splat pair.

It writes ``bench/bench_convert.py``'s synthetic lite PLY (1,000,000 splats,
128 MB by default) and its ``.splatv`` (``splatconv.convert``), then runs, each
in a fresh process started from the shell's point of view (the ``splatconv``
console script, interpreter start included):

* ``splatconv stats SCENE.ply SCENE.splatv`` (the pair),
* ``splatconv stats SCENE.ply`` (the conversion simulated in memory),
* ``splatconv stats SCENE.splatv`` (a file reported as stored),

at the default zstd level, and prints the median wall seconds and the peak RSS
(``ru_maxrss`` of the child, from ``os.wait4``) of ``--repeat`` runs, against
the targets (at most 10 s and 600 MB for the pair), and the CPU seconds (user +
system, all threads): on a machine shared with other jobs the wall time grows
with the load and the CPU time much less, so the CPU seconds bound what a quiet
machine takes. Figures vary from run to run; the exit status is 0 whatever they
are (a report, not a test).

Run::

    python bench/bench_stats.py [--splats N] [--repeat R] [--zstd-level L] [--keep DIR]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import splatconv
from splatconv.transport import DEFAULT_LEVEL

#: Targets for the pair: wall seconds and peak RSS in MB (10^6 bytes).
TARGET_SECONDS = 10.0
TARGET_RSS_MB = 600.0

CLI = os.path.join(os.path.dirname(sys.executable), "splatconv")

#: Launcher: run argv[1:] with stdout discarded, then print its exit code, wall seconds, ru_maxrss (KiB)
#: and CPU seconds (user + system, all threads).
LAUNCHER = """\
import os, subprocess, sys, time
t = time.perf_counter()
p = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL)
_, status, usage = os.wait4(p.pid, 0)
print("BENCH_CHILD", os.waitstatus_to_exitcode(status), time.perf_counter() - t, usage.ru_maxrss,
      usage.ru_utime + usage.ru_stime, flush=True)
"""


def make_ply(path: str, n: int) -> None:
    spec = importlib.util.spec_from_file_location("bench_convert", Path(__file__).with_name("bench_convert.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.make_ply(path, n)


def run(args: list) -> tuple[float, float, float]:
    """(wall seconds, peak RSS MB, CPU seconds) of one ``splatconv`` run."""
    out = subprocess.run([sys.executable, "-c", LAUNCHER, CLI, *args], capture_output=True, text=True,
                         check=True).stdout
    code, wall, rss, cpu = out.split("BENCH_CHILD", 1)[1].split()
    if int(code) != 0:
        raise SystemExit(f"splatconv {' '.join(args)} exited {code}")
    return float(wall), int(rss) * 1024 / 1e6, float(cpu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--zstd-level", type=int, default=DEFAULT_LEVEL)
    parser.add_argument("--keep", help="write the scenes to DIR and keep them")
    args = parser.parse_args()
    folder = args.keep or tempfile.mkdtemp(prefix="bench-stats-")
    os.makedirs(folder, exist_ok=True)
    ply, splatv = os.path.join(folder, "scene.ply"), os.path.join(folder, "scene.splatv")
    try:
        make_ply(ply, args.splats)
        splatconv.convert(ply, splatv, force=True)
        print(f"# splatconv stats: {args.splats:,} splats (PLY {os.path.getsize(ply) / 1e6:.0f} MB, .splatv "
              f"{os.path.getsize(splatv) / 1e6:.0f} MB), zstd level {args.zstd_level}; {platform.machine()}, "
              f"{os.cpu_count()} cores, Python {platform.python_version()}; medians of {args.repeat} runs")
        level = ["--zstd-level", str(args.zstd_level)]
        cases = [("pair: stats SCENE.ply SCENE.splatv", [ply, splatv]),
                 ("PLY alone (conversion simulated)", [ply]),
                 (".splatv alone (as stored)", [splatv])]
        print(f"{'':<36}  {'seconds':>9}  {'CPU s':>7}  {'peak RSS MB':>11}")
        pair = None
        for label, files in cases:
            runs = [run(["stats", *files, *level]) for _ in range(args.repeat)]
            wall = statistics.median(r[0] for r in runs)
            rss = statistics.median(r[1] for r in runs)
            cpu = statistics.median(r[2] for r in runs)
            pair = pair or (wall, rss)
            print(f"{label:<36}  {wall:>9.2f}  {cpu:>7.2f}  {rss:>11.0f}   (runs: "
                  + ", ".join(f"{r[0]:.2f} s" for r in runs) + ")", flush=True)
        wall, rss = pair
        print(f"\npair against the targets: {wall:.2f} s (target <= {TARGET_SECONDS:g} s: "
              f"{'met' if wall <= TARGET_SECONDS else 'NOT met'}), {rss:.0f} MB "
              f"(target <= {TARGET_RSS_MB:g} MB: {'met' if rss <= TARGET_RSS_MB else 'NOT met'})")
    finally:
        if not args.keep:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
