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
from pathlib import Path

import splatconv
from splatconv.zstd import DEFAULT_LEVEL

from _harness import CLI, machine_line, medians, run_fresh, work_folder

#: Targets for the pair: wall seconds and peak RSS in MB (10^6 bytes).
TARGET_SECONDS = 10.0
TARGET_RSS_MB = 600.0


def make_ply(path: str, n: int) -> None:
    spec = importlib.util.spec_from_file_location("bench_convert", Path(__file__).with_name("bench_convert.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.make_ply(path, n)


def run(args: list) -> dict:
    """Wall seconds, peak RSS (MB) and CPU seconds of one ``splatconv`` run in a fresh process
    (through :func:`_harness.run_fresh`'s launcher; its output discarded)."""
    r = run_fresh([CLI, *args], stdout="discard")
    if r["code"] != 0:
        raise SystemExit(f"splatconv {' '.join(args)} exited {r['code']}")
    return r


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--zstd-level", type=int, default=DEFAULT_LEVEL)
    parser.add_argument("--keep", help="write the scenes to DIR and keep them")
    args = parser.parse_args()
    with work_folder(args.keep, "bench-stats-") as folder:
        ply, splatv = os.path.join(folder, "scene.ply"), os.path.join(folder, "scene.splatv")
        make_ply(ply, args.splats)
        splatconv.convert(ply, splatv, force=True)
        print(f"# splatconv stats: {args.splats:,} splats (PLY {os.path.getsize(ply) / 1e6:.0f} MB, .splatv "
              f"{os.path.getsize(splatv) / 1e6:.0f} MB), zstd level {args.zstd_level}; {machine_line(numpy=False)}; "
              f"medians of {args.repeat} runs")
        level = ["--zstd-level", str(args.zstd_level)]
        cases = [("pair: stats SCENE.ply SCENE.splatv", [ply, splatv]),
                 ("PLY alone (conversion simulated)", [ply]),
                 (".splatv alone (as stored)", [splatv])]
        print(f"{'':<36}  {'seconds':>9}  {'CPU s':>7}  {'peak RSS MB':>11}")
        pair = None
        for label, files in cases:
            runs = [run(["stats", *files, *level]) for _ in range(args.repeat)]
            m = medians(runs, ("wall", "rss_mb", "cpu"), peak=())  # the median peak RSS, not the largest
            wall, rss, cpu = m["wall"], m["rss_mb"], m["cpu"]
            pair = pair or (wall, rss)
            print(f"{label:<36}  {wall:>9.2f}  {cpu:>7.2f}  {rss:>11.0f}   (runs: "
                  + ", ".join(f"{r['wall']:.2f} s" for r in runs) + ")", flush=True)
        wall, rss = pair
        print(f"\npair against the targets: {wall:.2f} s (target <= {TARGET_SECONDS:g} s: "
              f"{'met' if wall <= TARGET_SECONDS else 'NOT met'}), {rss:.0f} MB "
              f"(target <= {TARGET_RSS_MB:g} MB: {'met' if rss <= TARGET_RSS_MB else 'NOT met'})")


if __name__ == "__main__":
    main()
