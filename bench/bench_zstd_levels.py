"""Size and cost of zstd levels on realistic scenes: the figures behind ``DEFAULT_LEVEL``.

For each scene (1,000,000 splats by default) it writes the lite PLY and its
``.splatv`` (``splatconv.convert``), then compresses each file at zstd levels
1, 3, 6, 9, 12, 15 and 19 exactly as splatconv does (``splatconv.zstd.compressor``:
one worker per core, streamed), each in a fresh child process, and prints the
compressed size, how much larger it is than at the highest level, the seconds
of the compression (file read included, interpreter start not) and the
child's peak RSS. Scenes:

* ``sample``: the sample generator's scene (``sample_data/make_sample.py``: a
  ground disc, a moving ball, a spinning bar, fading clouds) with every shape
  scaled up to the splat count: smooth, structured attributes as trained scenes have;
* ``random``: ``bench/bench_convert.py``'s scene: independent random attributes,
  the hardest case for a compressor.

The machine is shared and noisy: compare levels within one run, not across runs.
It is a report, not a test: the exit status is 0 whatever the figures.

Run::

    python bench/bench_zstd_levels.py [--splats N] [--levels 1,3,19] [--scenes sample,random] [--keep DIR]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
from pathlib import Path

import numpy as np

import splatconv
from _harness import PYTHON, bench_fields, machine_line, run_fresh, work_folder

ROOT = Path(__file__).resolve().parent.parent
LEVELS = (1, 3, 6, 9, 12, 15, 19)

#: Child: compress argv[1] at level argv[2] as splatconv does; print the compressed bytes.
CHILD = """\
import os, sys, time
from splatconv.zstd import compressor
class Sink:
    count = 0
    def write(self, data):
        self.count += memoryview(data).nbytes
        return memoryview(data).nbytes
sink = Sink()
size = os.path.getsize(sys.argv[1])
t = time.perf_counter()
with open(sys.argv[1], "rb") as f, compressor(int(sys.argv[2])).stream_writer(sink, size=size, closefd=False) as z:
    while chunk := f.read(1 << 22):
        z.write(chunk)
print("BENCH_BYTES", sink.count, time.perf_counter() - t)
"""


def _module(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def make_sample_ply(path: str, n: int) -> None:
    """The sample generator's scene with each shape's splat count scaled so the total is about ``n``."""
    sample = _module(ROOT / "sample_data" / "make_sample.py", "make_sample")
    shapes = [(sample.make_ground, 1800), (sample.make_ball, 1000), (sample.make_bar, 900),
              (sample.make_blue, 700), (sample.make_burst, 600)]
    total = sum(count for _, count in shapes)
    rng = np.random.default_rng(sample.SEED)
    rows = np.concatenate([make(rng, max(1, round(count * n / total))) for make, count in shapes])
    Path(path).write_bytes(sample.ply_bytes(rows))


def make_random_ply(path: str, n: int) -> None:
    _module(ROOT / "bench" / "bench_convert.py", "bench_convert").make_ply(path, n)


SCENES = {"sample": make_sample_ply, "random": make_random_ply}


def compress(path: str, level: int) -> dict:
    """Compressed bytes, seconds and peak RSS (MB) of compressing ``path`` at ``level`` in a
    fresh process (through :func:`_harness.run_fresh`'s launcher)."""
    r = run_fresh([PYTHON, "-c", CHILD, path, str(level)])
    if r["code"] != 0:
        raise SystemExit(f"compressing {path} at level {level} failed")
    nbytes, seconds = bench_fields(r["stdout"])["BENCH_BYTES"]
    return {"bytes": int(nbytes), "seconds": float(seconds), "rss_mb": r["rss_mb"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--levels", default=",".join(map(str, LEVELS)))
    parser.add_argument("--scenes", default=",".join(SCENES))
    parser.add_argument("--keep", help="write the scenes to DIR and keep them")
    args = parser.parse_args()
    levels = [int(v) for v in args.levels.split(",")]
    print(f"# zstd levels: {args.splats:,} splats; {machine_line(numpy=False)}")
    with work_folder(args.keep, "bench-zstd-") as folder:
        for scene in args.scenes.split(","):
            ply = os.path.join(folder, f"{scene}.ply")
            splatv = os.path.join(folder, f"{scene}.splatv")
            SCENES[scene](ply, args.splats)
            splatconv.convert(ply, splatv, force=True)
            results = {(kind, level): compress(path, level) for kind, path in (("splatv", splatv), ("ply", ply))
                       for level in levels}
            print(f"\n## {scene}: .splatv {os.path.getsize(splatv) / 1e6:.1f} MB, "
                  f"PLY {os.path.getsize(ply) / 1e6:.1f} MB")
            top = max(levels)
            print(f"{'level':>5}  {'.splatv MB':>10}  {'vs ' + str(top):>7}  {'s':>6}  {'RSS MB':>6}  "
                  f"{'PLY MB':>7}  {'vs ' + str(top):>7}  {'s':>6}  {'RSS MB':>6}")
            for level in levels:
                cells = []
                for kind in ("splatv", "ply"):
                    r, best = results[(kind, level)], results[(kind, top)]["bytes"]
                    cells.append(f"{r['bytes'] / 1e6:>{10 if kind == 'splatv' else 7}.2f}  "
                                 f"{100 * (r['bytes'] / best - 1):>+6.1f}%  {r['seconds']:>6.2f}  {r['rss_mb']:>6.0f}")
                print(f"{level:>5}  " + "  ".join(cells), flush=True)


if __name__ == "__main__":
    main()
