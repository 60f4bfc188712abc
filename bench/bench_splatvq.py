"""``.splatvq``: bytes a splat and fidelity per setting, the entropy coder's trade-off, and cost against ``.splatv``.

On generated scenes with what real trained scenes hold (zero rotations, NaN
and huge positions, infinite temporal scales, flat splats, a large background,
fast movers among mostly slow splats):

* per setting: bytes of the file divided by the source's drawable splats, and
  the worst and mean PSNR of the decoded scene against the source, both drawn
  with the viewer's maths (float reference path) from the scene's camera at
  640x480 at t = 0.1, 0.3, 0.5, 0.7, 0.9;
* the same blocks coded with raw deflate (what the format stores: the browser's
  ``DecompressionStream('deflate-raw')``) and with zstd (what a vendored fzstd
  would decode), and how long Python takes to decompress each;
* the same per setting on the real trained scenes in ``../shared/real`` (``--real``;
  frames from each scene's first camera, drawn with the viewer's GL path, the
  ``.splatv`` as read against its decoded ``.splatvq``), said plainly when absent;
* ``convert`` of a PLY to ``.splatv`` and to ``.splatvq``, and of each back to a
  PLY, in fresh processes: wall seconds and peak RSS (the issue's bounds: encoding
  at most 4x, decoding at most 2x, memory at most 2x the ``.splatv`` figures).

Run::

    python bench/bench_splatvq.py [--splats 200000] [--timing-splats 1000000] [--real DIR] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import zlib

import numpy as np

import _harness
from splatconv.formats import ply, splatvq
from splatconv.formats import splatvq_codec as codec
from splatconv.model import COLUMNS, Scene
from splatconv.render.diff import compare
from splatconv.render.frames import render_scene
from splatconv.viewer import undrawable

TIMES = (0.1, 0.3, 0.5, 0.7, 0.9)
CAMERA = {"id": 0, "img_name": "bench", "width": 640, "height": 480, "position": [0.0, 0.0, -8.0],
          "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "fx": 600.0, "fy": 600.0}


def make_scene(n: int, seed: int = 0) -> Scene:
    """A scene of ``n`` splats with real-scene properties, in front of :data:`CAMERA`.

    Foreground blobs (65%), a background shell 30 to 100 units out (15%), zero
    rotations (20%, undrawable), NaN positions (0.5%), huge positions (0.1%),
    infinite temporal scales (10%), flat splats (2%); 8% fast movers.
    """
    rng = np.random.default_rng(seed)
    c = {}
    blobs = rng.normal(0, 1.2, (64, 3))
    which = rng.integers(0, 64, n)
    pos = blobs[which] + rng.normal(0, 0.35, (n, 3))
    back = rng.random(n) < 0.15
    direction = rng.normal(0, 1, (n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    pos[back] = direction[back] * rng.uniform(30, 100, (n, 1))[back]
    for i, name in enumerate("xyz"):
        c[name] = pos[:, i]
    c["trbf_center"] = rng.uniform(0, 1, n)
    c["trbf_scale"] = np.log(rng.uniform(0.08, 1.5, n))
    fast = rng.random(n) < 0.08
    for i in range(9):
        sigma = (0.05, 0.03, 0.02)[i // 3]
        m = rng.normal(0, sigma, n)
        m[fast] = rng.normal(0, (1.5, 0.8, 0.5)[i // 3], int(fast.sum()))
        c[f"motion_{i}"] = m
    for i in range(3):
        c[f"f_dc_{i}"] = rng.uniform(0.0, 1.0, n)
        c[f"scale_{i}"] = rng.normal(-4.2, 0.6, n) + np.where(back, 2.5, 0.0)
    c["opacity"] = rng.normal(0.5, 2.0, n)
    for i in range(4):
        c[f"rot_{i}"] = rng.normal(0, 1, n)
        c[f"omega_{i}"] = rng.normal(0, 0.3, n)
    zero = rng.random(n) < 0.20
    for name in ("rot_0", "rot_1", "rot_2", "rot_3", "omega_0", "omega_1", "omega_2", "omega_3"):
        c[name][zero] = 0.0
    c["x"][rng.random(n) < 0.005] = np.nan
    c["y"][rng.random(n) < 0.001] = 3e30
    c["trbf_scale"][rng.random(n) < 0.10] = np.inf
    c["scale_2"][rng.random(n) < 0.02] = -np.inf
    with np.errstate(invalid="ignore", over="ignore"):
        cols = {k: np.asarray(c[k], dtype=np.float32) for k in COLUMNS}
    return Scene(cols, cameras=[dict(CAMERA)])


def fidelity(source: Scene, decoded: Scene) -> tuple[float, float]:
    """Worst and mean PSNR over :data:`TIMES`, both drawn with the float reference path."""
    a = render_scene(source, CAMERA, TIMES, size=(640, 480))
    b = render_scene(decoded, CAMERA, TIMES, size=(640, 480))
    values = [compare(x, y).psnr for x, y in zip(a, b)]
    return min(values), float(np.mean(values))


def coders(data: bytes) -> dict:
    """Sizes and Python decode seconds of the file's blocks as stored (deflate) and recoded with zstd."""
    import zstandard

    setting, _meta, blocks = splatvq._header(_BytesFile(data), "<bench>", len(data))
    out = {"deflate": [0, 0.0], "zstd-19": [0, 0.0], "zstd-9": [0, 0.0], "raw": sum(b.raw for b in blocks)}
    for block in blocks:
        chunk = data[block.offset:block.offset + block.stored]
        t = time.perf_counter()
        payload = zlib.decompress(chunk, -15)
        out["deflate"][1] += time.perf_counter() - t
        out["deflate"][0] += block.stored
        for name, level in (("zstd-19", 19), ("zstd-9", 9)):
            z = zstandard.ZstdCompressor(level=level).compress(payload)
            t = time.perf_counter()
            zstandard.ZstdDecompressor().decompress(z)
            out[name][1] += time.perf_counter() - t
            out[name][0] += len(z)
    return out


class _BytesFile:
    def __init__(self, data):
        self.data, self.at = data, 0

    def read(self, k):
        self.at += k
        return self.data[self.at - k:self.at]


def quality_table(n: int, seeds) -> None:
    print(f"scenes: {n:,} splats, seeds {', '.join(map(str, seeds))}; camera 640x480; t = {', '.join(map(str, TIMES))}")
    print(f"{'setting':<9} {'seed':>4} {'drawable':>9} {'B/splat':>8} {'worst dB':>9} {'mean dB':>8} {'raw':>6} "
          f"{'zstd-19 B':>10} {'zstd-9 B':>9} {'inflate s':>10} {'zstd s':>7}")
    scenes = [make_scene(n, seed) for seed in seeds]
    for name in codec.SETTINGS:
        rows = []
        for seed, scene in zip(seeds, scenes):
            drawable = int(np.count_nonzero(~undrawable(scene.columns)))
            data, _report = splatvq.encode(scene, quality=name)
            path = os.path.join(WORK, f"q_{name}_{seed}.splatvq")
            with open(path, "wb") as f:
                f.write(data)
            decoded = splatvq.read(path)
            worst, mean = fidelity(scene, decoded)
            sizes = coders(data)
            header = len(data) - sizes["deflate"][0]
            rows.append((len(data) / drawable, worst))
            print(f"{name:<9} {seed:>4} {drawable:>9,} {len(data) / drawable:8.2f} {worst:9.2f} {mean:8.2f} "
                  f"{sizes['raw']:6d} {(sizes['zstd-19'][0] + header) / drawable:10.2f} "
                  f"{(sizes['zstd-9'][0] + header) / drawable:9.2f} {sizes['deflate'][1]:10.3f} {sizes['zstd-19'][1]:7.3f}")
        print(f"{name:<9} {'all':>4} {'':>9} {max(b for b, _ in rows):8.2f} {min(w for _, w in rows):9.2f}   "
              "(largest size, worst frame)")
    print("(.splatv: 64 B a splat)")


#: Real trained scenes, beside the repository (never in it).
REAL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "real")
REAL_SCENES = ("coffeeshort2.splatv", "yellow_clip3.splatv")


def real_table(folder: str) -> None:
    """What ``convert`` writes on the real scenes found in ``folder``, per setting: bytes a drawable splat, the
    proof's worst and mean frame (every proof view) and camera 0's worst and mean alone; then --prune."""
    import splatconv
    from splatconv.jobs.prove import write_proven

    found = [name for name in REAL_SCENES if os.path.isfile(os.path.join(folder, name))]
    print(f"\nreal scenes in {os.path.normpath(folder)}: convert's proof (its views, t = 0.1..0.9), and camera 0 "
          f"alone, 640x480, t = {', '.join(map(str, TIMES))}")
    if not found:
        print(f"  absent: none of {', '.join(REAL_SCENES)} is there; no real-scene figures")
        return
    print(f"{'scene':<14} {'run':<22} {'drawable':>9} {'B/splat':>8} {'proof worst':>12} {'mean':>6} "
          f"{'cam0 worst':>11} {'mean':>6} {'step':>10} {'s':>6}")
    for name in found:
        scene = splatconv.read(os.path.join(folder, name))
        camera = scene.cameras[0]
        drawable = int(np.count_nonzero(~undrawable(scene.columns)))
        source = render_scene(scene, camera, TIMES, size=(640, 480), reference=False)
        runs = [(setting, {"quality": setting}) for setting in codec.SETTINGS]
        runs.append(("--min-psnr 40 --prune", {"quality": None, "min_psnr": 40.0, "prune": True}))
        for label, options in runs:
            path = os.path.join(WORK, "real.splatvq")
            started = time.perf_counter()
            _report, notes = write_proven(scene, path, force=True, **options)
            seconds = time.perf_counter() - started
            proved = next(n for n in notes if n.startswith("proved: "))
            worst = float(proved.split("worst frame ")[1].split(" dB")[0])
            mean = float(proved.split("mean ")[1].split(" dB")[0])
            decoded = splatvq.read(path)
            frames = render_scene(decoded, camera, TIMES, size=(640, 480), reference=False)
            values = [compare(x, y).psnr for x, y in zip(source, frames)]
            print(f"{name.rsplit('.', 1)[0]:<14} {label:<22} {drawable:>9,} {os.path.getsize(path) / drawable:8.2f} "
                  f"{worst:12.2f} {mean:6.2f} {min(values):11.2f} {float(np.mean(values)):6.2f} "
                  f"{decoded.meta['setting']:>10} {seconds:6.1f}")
    print("(bytes of the file over the source's drawable splats; --prune's file holds fewer)")


def cost_table(n: int) -> None:
    src = os.path.join(WORK, "timing.ply")
    scene = make_scene(n, seed=1)
    with open(src, "wb") as f:
        ply.write(scene, f)
    del scene
    print(f"\nconvert, fresh processes, {n:,} splats ({_harness.machine_line(load=True)})")
    rows = {}
    for label, suffix, more in ((".splatv", ".splatv", []), (".splatvq --no-proof", ".splatvq", ["--no-proof"]),
                                (".splatvq (proved)", ".splatvq", [])):
        out = os.path.join(WORK, "timing" + suffix)
        enc = _harness.run_fresh([_harness.CLI, "convert", src, out, "--force", "--quiet", *more], check=True)
        back = os.path.join(WORK, "back" + suffix.replace(".", "_") + ".ply")
        dec = _harness.run_fresh([_harness.CLI, "convert", out, back, "--force", "--quiet"], check=True)
        rows[label] = (enc, dec, os.path.getsize(out))
        print(f"{label:<20} encode {enc['wall']:6.2f} s {enc['rss_mb']:7.0f} MB   decode {dec['wall']:6.2f} s "
              f"{dec['rss_mb']:7.0f} MB   {os.path.getsize(out) / 1e6:8.1f} MB file")
    e1, d1, _ = rows[".splatv"]
    for label in (".splatvq --no-proof", ".splatvq (proved)"):
        e2, d2, _ = rows[label]
        print(f"ratios {label:<20} encode {e2['wall'] / e1['wall']:.2f}x time {e2['rss_mb'] / e1['rss_mb']:.2f}x RSS   "
              f"decode {d2['wall'] / d1['wall']:.2f}x time {d2['rss_mb'] / d1['rss_mb']:.2f}x RSS "
              "(bounds 20x with the proof, 2x, 2x)")


def main(argv=None) -> int:
    global WORK
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--splats", type=int, default=200_000)
    p.add_argument("--seeds", default="0,1,2", help="scenes to measure, by seed (comma-separated)")
    p.add_argument("--timing-splats", type=int, default=1_000_000)
    p.add_argument("--real", default=REAL, help="folder of the real trained scenes (default ../shared/real)")
    p.add_argument("--keep")
    args = p.parse_args(argv)
    with _harness.work_folder(args.keep) as WORK:
        quality_table(args.splats, [int(x) for x in args.seeds.split(",")])
        real_table(args.real)
        if args.timing_splats:
            cost_table(args.timing_splats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
