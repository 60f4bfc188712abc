"""Wall time and peak memory of ``splatconv verify`` on a 1M-splat scene.

Makes the synthetic Spacetime Gaussians lite PLY of ``bench_convert.py`` (N
splats, default 1,000,000; no cameras, so verify draws from one framing
camera), converts it to ``.splatv``, then runs ``python -m splatconv verify
SOURCE CONVERTED --json`` in a fresh process, several times:

* with verify's defaults (5 times from the first cameras at 640 wide): the
  figure the targets are about (at most 30 s and 800 MB peak RSS);
* with 4 times as many frames (``--times`` of 20 values): peak RSS must not grow
  with the number of frames, since no frame's images are kept;
* once more through the library with a timing progress reporter, to show where
  the seconds go (reading, checking attributes, drawing).

Wall seconds include interpreter start; peak RSS is the child's ``ru_maxrss``
from ``os.wait4`` (so it is that verify's alone), as are its CPU seconds (user +
system, all threads: llvmpipe draws on every core, so on an idle machine wall
time is about CPU time over the cores it keeps busy). The load average is
printed before and after: on a shared machine wall time swings with it, CPU
time much less. The exit status is 0 whatever the figures.

Run::

    python bench/bench_verify.py [--splats N] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from _harness import load_average, machine_line, run_fresh, work_folder  # noqa: E402
from bench_convert import make_ply  # noqa: E402  (the same generator as the conversion benchmark)

#: Targets from the issue: seconds and MB (10^6 bytes) of peak RSS.
TARGET_SECONDS = 30.0
TARGET_RSS_MB = 800.0

#: Child: verify through the library, printing each stage's seconds.
STAGES = """\
import contextlib, sys, time
from splatconv.progress import Progress
from splatconv.render.verify import verify

class Timing(Progress):
    @contextlib.contextmanager
    def stage(self, label, total=None, unit="it"):
        t = time.perf_counter()
        yield lambda n=1: None
        print(f"stage {label}: {time.perf_counter() - t:.2f} s", flush=True)

t = time.perf_counter()
outcome = verify(sys.argv[1], sys.argv[2], progress=Timing())
print(f"verify(): {time.perf_counter() - t:.2f} s, {len(outcome.frames)} frames, passed {outcome.passed}")
"""


def run_child(argv: list) -> dict:
    """Run ``argv``; its exit code, stdout, stderr, wall and CPU seconds and peak RSS (MB) from ``os.wait4``.

    Started through the harness's small launcher process, so that the peak RSS is the command's
    own: a child started straight from this process inherits this process's high-water mark in
    ``ru_maxrss`` (the generated scene), which could hide or inflate verify's own.
    """
    return run_fresh(argv)


def verify_cli(src: str, out: str, *extra) -> dict:
    r = run_child([sys.executable, "-m", "splatconv", "verify", src, out, "--json", "-q", *extra])
    if r["code"] not in (0, 1):
        raise SystemExit(f"verify failed ({r['code']}): {r['stderr'].strip()}")
    data = json.loads(r["stdout"])
    r["frames"], r["passed"] = len(data["frames"]), data["passed"]
    r["worst"] = data["worst"]["psnr"] if data["worst"] else None
    return r


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--splats", type=int, default=1_000_000)
    ap.add_argument("--keep", help="Folder for the generated files (kept); default a temporary one.")
    args = ap.parse_args(argv)
    with work_folder(args.keep, "bench_verify_") as work:
        return run(args, work)


def run(args, work: str) -> int:
    import splatconv

    n = args.splats
    src, out = os.path.join(work, "scene.ply"), os.path.join(work, "scene.splatv")
    print(f"splatconv {splatconv.__version__} verify benchmark -- {machine_line(numpy=False, load=True)}")
    t = time.perf_counter()
    size = make_ply(src, n)
    print(f"input: {n:,} splats, {size / 1e6:.1f} MB lite PLY (generated in {time.perf_counter() - t:.1f} s)")
    conv = run_child([sys.executable, "-m", "splatconv", "convert", src, out, "-q", "--force"])
    if conv["code"]:
        raise SystemExit(f"convert failed: {conv['stderr'].strip()}")
    print(f"convert: {conv['wall']:.1f} s, peak RSS {conv['rss_mb']:.0f} MB")

    default = verify_cli(src, out)
    times = ",".join(f"{k / 19:.4f}" for k in range(20))
    many = verify_cli(src, out, "--times", times)
    for label, r in (("verify (defaults)", default), ("verify (20 times)", many)):
        print(f"{label}: {r['wall']:.1f} s wall, {r['cpu']:.1f} s CPU, peak RSS {r['rss_mb']:.0f} MB, {r['frames']} frames, "
              f"passed {r['passed']}, worst PSNR {r['worst']} dB")
    stages = run_child([sys.executable, "-c", STAGES, src, out])
    print("where the time goes (library call, fresh process):")
    for line in stages["stdout"].splitlines():
        print(f"  {line}")
    print(f"  peak RSS {stages['rss_mb']:.0f} MB")

    print(f"load average now {load_average()}")
    growth = many["rss_mb"] - default["rss_mb"]
    print(f"memory with 4x the frames: {growth:+.0f} MB ({'does not grow' if growth < 25 else 'GROWS'})")
    if n != 1_000_000:
        print("(the targets below are for 1,000,000 splats)")
    ok_time, ok_rss = default["wall"] <= TARGET_SECONDS, default["rss_mb"] <= TARGET_RSS_MB
    print(f"target: <= {TARGET_SECONDS:.0f} s: {'met' if ok_time else 'MISSED'} ({default['wall']:.1f} s); "
          f"<= {TARGET_RSS_MB:.0f} MB: {'met' if ok_rss else 'MISSED'} ({default['rss_mb']:.0f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
