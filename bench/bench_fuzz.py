"""A long fuzz campaign over every reader: prints what it ran and what it found.

The mutants come from :mod:`tests.fuzzing` (the same mutators, seeds and checks as
the short campaign in ``tests/test_fuzz.py``): bit flips, byte values,
truncations, extensions, PLY and ``.splatv`` header edits (deleted, duplicated,
swapped lines; other types and formats; deep nesting and numbers past a double in
the JSON), huge or negative counts, and zstd bombs. Each mutant is run through
every command of ``tests.fuzzing._commands`` in-process (``info``, ``info --json``,
``stats``, ``convert`` to ``.splatv``, ``.ply``, ``.splat`` and ``.html``, ``bake``,
``render`` and ``diff``); a mutant fails on a traceback, a warning, an exit status other than
0 or 1 (1 with exactly one ``Error:`` line), a file left behind, a changed input,
more than 120 s (a hang) or more than 512 MiB of traced memory. Failing mutants are kept
in ``--keep`` (default: a temporary folder, removed).

Run::

    python bench/bench_fuzz.py [--mutants N] [--seed S] [--keep DIR]

The exit status is 1 when any mutant failed, else 0.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import time
from collections import Counter

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from _harness import new_work_folder  # noqa: E402
from tests.fuzzing import CAMPAIGN_MAX_DECOMPRESSED, campaign  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mutants", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--keep", help="folder for the campaign's files (kept)")
    args = parser.parse_args()
    folder = new_work_folder(args.keep, "splatconv-fuzz-")  # removed at the end unless kept or a mutant failed
    started = time.perf_counter()
    done = [0]

    def progress(outcome):
        done[0] += 1
        if done[0] % 100 == 0:
            print(f"  {done[0]:,} mutants, {time.perf_counter() - started:.0f} s", file=sys.stderr, flush=True)

    outcomes = campaign(folder, args.seed, args.mutants, progress)
    total = time.perf_counter() - started
    failures = [o for o in outcomes if o.problems]
    seconds = sorted(o.seconds for o in outcomes)
    codes = Counter(code for o in outcomes for code in o.exit_codes)
    kinds = Counter(k if not k.startswith("zstd bomb") else "zstd bomb" for o in outcomes for k in o.kind.split("+"))
    seeds = Counter(o.name for o in outcomes)
    print(f"fuzz campaign: {len(outcomes):,} mutants, seed {args.seed}, {total:.1f} s "
          f"(decompression ceiling {CAMPAIGN_MAX_DECOMPRESSED})")
    print(f"  commands run:      {sum(codes.values()):,} (exit 0: {codes[0]:,}, exit 1: {codes[1]:,}, "
          f"other: {sum(v for k, v in codes.items() if k not in (0, 1)):,})")
    print("  mutations:         " + ", ".join(f"{k} {v:,}" for k, v in sorted(kinds.items())))
    print("  seed files:        " + ", ".join(f"{k} {v:,}" for k, v in sorted(seeds.items())))
    print(f"  seconds a mutant:  median {statistics.median(seconds):.3f}, p99 "
          f"{seconds[min(len(seconds) - 1, int(0.99 * len(seconds)))]:.3f}, max {seconds[-1]:.3f} "
          f"({len(outcomes[0].exit_codes)} commands, in-process, memory traced)")
    peaks = sorted(o.traced_peak for o in outcomes)
    print(f"  traced memory peak: median {statistics.median(peaks) / 2**20:.1f} MiB, max {peaks[-1] / 2**20:.1f} MiB")
    slowest = max(outcomes, key=lambda o: o.seconds)
    print(f"  slowest mutant:    #{slowest.index} {slowest.name} [{slowest.kind}] {slowest.seconds:.2f} s")
    print(f"  failures:          {len(failures)}")
    for o in failures[:50]:
        print(f"    #{o.index} {o.name} [{o.kind}]: {'; '.join(o.problems)}")
    if failures:
        print(f"  failing mutants kept in {folder}")
    elif not args.keep:
        shutil.rmtree(folder, ignore_errors=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
