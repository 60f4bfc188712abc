"""Benchmark the PLY reader on the inputs that used to be slow paths.

What it measures (``splatconv.read``, in-process, median of ``--repeat`` runs,
file in the page cache):

* a binary Spacetime Gaussians lite PLY of ``--splats`` rows (1,000,000 by
  default) with one extra list property of constant length (3 floats a row):
  the reader assumes every row has the first row's list lengths and checks that
  for all rows at once;
* the same with list lengths that vary (2 and 3 alternately): the rows are
  walked one by one to find where each starts, the columns then gathered in bulk;
* the plain file, no list (the floor: a mapped view);
* an ASCII lite PLY of ``--ascii-rows`` rows (200,000 by default), parsed by
  ``numpy.loadtxt``.

With ``--plyfile`` it also times ``plyfile.PlyData.read`` on the same files,
which is what splatconv called before (row by row in Python for elements with
list properties and for ASCII). Figures vary with the machine's load: run it on
a quiet machine and compare medians. The exit status is 0 whatever the figures.

Run::

    python bench/bench_ply_read.py [--splats N] [--ascii-rows M] [--repeat R] [--plyfile]
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
import plyfile

import splatconv
from splatconv.formats import ply

from _harness import median_seconds, work_folder


def _columns(n: int, seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    return {name: rng.normal(0, 1, n).astype(np.float32) for name in ply.LITE_LAYOUT}


def _header(n: int, fmt: str, extra: str = "") -> bytes:
    lines = ["ply", f"format {fmt} 1.0", f"element vertex {n}"]
    lines += [f"property float {name}" for name in ply.LITE_LAYOUT]
    if extra:
        lines.append(extra)
    lines.append("end_header\n")
    return "\n".join(lines).encode()


def _rows(cols: dict, list_len: int | None) -> np.ndarray:
    fields = [(name, "<f4") for name in ply.LITE_LAYOUT]
    if list_len is not None:
        fields += [("n", "u1"), ("values", "<f4", (list_len,))]
    arr = np.zeros(len(cols["x"]), fields)
    for name in ply.LITE_LAYOUT:
        arr[name] = cols[name]
    if list_len is not None:
        arr["n"] = list_len
        arr["values"] = 1.5
    return arr


def make_files(folder: str, n: int, ascii_rows: int) -> dict:
    cols = _columns(n)
    files = {}
    path = os.path.join(folder, "plain.ply")
    with open(path, "wb") as f:
        f.write(_header(n, "binary_little_endian") + _rows(cols, None).tobytes())
    files["binary, no list"] = path
    path = os.path.join(folder, "list.ply")
    with open(path, "wb") as f:
        f.write(_header(n, "binary_little_endian", "property list uchar float values")
                + _rows(cols, 3).tobytes())
    files["binary + list of 3"] = path
    # Lengths 2 and 3 alternately: pairs of rows as one record type.
    half = n // 2
    a = _rows({k: v[0:2 * half:2] for k, v in cols.items()}, 2)
    b = _rows({k: v[1:2 * half:2] for k, v in cols.items()}, 3)
    pair = np.zeros(half, [("a", a.dtype), ("b", b.dtype)])
    pair["a"], pair["b"] = a, b
    path = os.path.join(folder, "varying.ply")
    with open(path, "wb") as f:
        f.write(_header(2 * half, "binary_little_endian", "property list uchar float values") + pair.tobytes())
    files["binary + list of 2 or 3"] = path
    path = os.path.join(folder, "ascii.ply")
    table = np.stack([cols[name][:ascii_rows] for name in ply.LITE_LAYOUT], axis=1)
    with open(path, "wb") as f:
        f.write(_header(ascii_rows, "ascii"))
        np.savetxt(f, table, fmt="%.9g")
    files[f"ascii, {ascii_rows:,} rows"] = path
    return files


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--splats", type=int, default=1_000_000)
    parser.add_argument("--ascii-rows", type=int, default=200_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--plyfile", action="store_true", help="also time plyfile.PlyData.read (slow: minutes)")
    args = parser.parse_args()
    with work_folder(prefix="splatconv-bench-") as folder:
        files = make_files(folder, args.splats, args.ascii_rows)
        print(f"PLY read, {args.splats:,} binary rows, median of {args.repeat} (seconds)")
        print(f"  {'file':<28} {'MB':>8} {'splatconv':>10}" + (f" {'plyfile':>10}" if args.plyfile else ""))
        for label, path in files.items():
            for _ in range(2):
                with open(path, "rb") as f:  # into the page cache
                    while f.read(1 << 24):
                        pass
            ours = median_seconds(lambda: splatconv.read(path).columns["x"].sum(), args.repeat)
            line = f"  {label:<28} {os.path.getsize(path) / 1e6:>8.1f} {ours:>10.3f}"
            if args.plyfile:
                theirs = median_seconds(lambda: plyfile.PlyData.read(path, mmap="r")["vertex"].data["x"].sum(), 1)
                line += f" {theirs:>10.3f}"
            print(line, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
