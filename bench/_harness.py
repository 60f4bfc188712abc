"""What the benchmarks share: work folder, fresh-process runs, medians, machine line.

The benchmarks are run as scripts (``python bench/bench_x.py``), so their own
folder is first on ``sys.path`` and they import this module as ``_harness``.
Standard library only (numpy only for its version, in :func:`machine_line`).

* :func:`work_folder`: the folder a benchmark writes its inputs and outputs to
  (``--keep DIR``, or a temporary one removed afterwards);
* :func:`run_fresh`: run a command in a fresh process and measure it: exit
  code, wall seconds, CPU seconds and peak RSS, from ``os.wait4``;
  :func:`bench_fields` reads the figures a child printed on ``BENCH...`` lines;
* :func:`median_seconds` (time a call) and :func:`medians` (figures of several
  runs);
* :func:`machine_line` and :func:`load_average`: what machine the figures come
  from; :func:`row`: one line of a two-column text table.
"""

from __future__ import annotations

import contextlib
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

#: The interpreter running the benchmark; children run under it too.
PYTHON = sys.executable
#: The ``splatconv`` console script installed beside that interpreter.
CLI = os.path.join(os.path.dirname(sys.executable), "splatconv")

#: Launcher: run argv[2:] as a child (its stdout discarded when argv[1] is
#: "discard"), then print its exit code, wall seconds, ru_maxrss (KiB) and CPU
#: seconds (user + system, all threads) on a BENCH_CHILD line.
LAUNCHER = """\
import os, subprocess, sys, time
t = time.perf_counter()
p = subprocess.Popen(sys.argv[2:], stdout=subprocess.DEVNULL if sys.argv[1] == "discard" else None)
_, status, usage = os.wait4(p.pid, 0)
wall = time.perf_counter() - t
sys.stdout.flush()
print("BENCH_CHILD", os.waitstatus_to_exitcode(status), wall, usage.ru_maxrss, usage.ru_utime + usage.ru_stime,
      flush=True)
"""


def new_work_folder(keep: str | None = None, prefix: str = "splatconv-bench-") -> str:
    """The folder ``keep`` (made if missing), or a new temporary folder named ``prefix...``.

    For a benchmark that decides itself whether to remove it afterwards
    (``bench_fuzz.py`` keeps it when a mutant failed); others use :func:`work_folder`.
    """
    if keep:
        os.makedirs(keep, exist_ok=True)
        return keep
    return tempfile.mkdtemp(prefix=prefix)


@contextlib.contextmanager
def work_folder(keep: str | None = None, prefix: str = "splatconv-bench-"):
    """Yield the folder a benchmark works in: ``keep`` (made if missing and left
    there afterwards, as ``--keep DIR`` asks) or a new temporary folder named
    ``prefix...``, removed with all it holds when the block ends, however it ends."""
    folder = new_work_folder(keep, prefix)
    try:
        yield folder
    finally:
        if not keep:
            shutil.rmtree(folder, ignore_errors=True)


def run_fresh(argv: list, *, launcher: bool = True, stdout: str = "capture", check: bool = False) -> dict:
    """Run ``argv`` in a fresh process and wait for it; what it printed and what it cost.

    Returns a dict: ``code`` (exit code; negative: killed by that signal),
    ``wall`` (seconds from start to exit), ``cpu`` (user + system seconds, all
    its threads, from ``os.wait4``), ``rss_mb`` (its peak RSS: ``ru_maxrss``
    from ``os.wait4``, in MB of 10^6 bytes), ``stdout`` and ``stderr`` (text;
    ``stdout`` is empty when ``stdout="discard"``, which sends it to
    ``/dev/null``).

    ``launcher=True`` (the default): the command is started by a small launcher
    process (:data:`LAUNCHER`), not by this one, which measures it and reports
    on a ``BENCH_CHILD`` line (taken out of ``stdout`` here). Linux carries the
    RSS high-water mark of the process that starts a command into the
    command's ``ru_maxrss``, and a benchmark's high-water mark includes the
    inputs it generated; the launcher is small, so the figure is the command's
    own. ``launcher=False``: this process starts the command itself (output to
    temporary files, so a large output cannot block it); the peak RSS is then
    at least this process's own high-water mark. ``bench_verify.py`` measures
    that way.

    ``check``: raise :class:`RuntimeError` with the command's output when it
    exits with a code other than 0. A launcher that fails (or reports nothing)
    raises :class:`RuntimeError` whatever ``check`` says.
    """
    if stdout not in ("capture", "discard"):
        raise ValueError(f"stdout must be 'capture' or 'discard', not {stdout!r}")
    sink = subprocess.DEVNULL if stdout == "discard" else None
    if launcher:
        p = subprocess.run([PYTHON, "-c", LAUNCHER, stdout, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        out, err = p.stdout.decode("utf-8", "replace"), p.stderr.decode("utf-8", "replace")
        out, found, report = out.rpartition("BENCH_CHILD ")
        if p.returncode != 0 or not found:
            raise RuntimeError(f"{' '.join(argv)} failed (launcher exit {p.returncode}):\n{out}{report}{err}")
        code, wall, maxrss_kib, cpu = report.split()
        result = {"code": int(code), "wall": float(wall), "cpu": float(cpu), "rss_mb": int(maxrss_kib) * 1024 / 1e6,
                  "stdout": out, "stderr": err}
    else:
        with tempfile.TemporaryFile() as out_file, tempfile.TemporaryFile() as err_file:
            t = time.perf_counter()
            p = subprocess.Popen(argv, stdout=sink if sink is not None else out_file, stderr=err_file)
            _, status, usage = os.wait4(p.pid, 0)
            wall = time.perf_counter() - t
            p.returncode = os.waitstatus_to_exitcode(status)
            out_file.seek(0)
            err_file.seek(0)
            result = {"code": p.returncode, "wall": wall, "cpu": usage.ru_utime + usage.ru_stime,
                      "rss_mb": usage.ru_maxrss * 1024 / 1e6, "stdout": out_file.read().decode("utf-8", "replace"),
                      "stderr": err_file.read().decode("utf-8", "replace")}
    if check and result["code"] != 0:
        raise RuntimeError(f"{' '.join(argv)} failed (exit {result['code']}):\n{result['stdout']}{result['stderr']}")
    return result


def bench_fields(text: str) -> dict:
    """The figures a child printed: ``{first word: [the other words]}`` of each
    line of ``text`` whose first word starts with ``BENCH`` (``BENCH_SECONDS 0.41``
    gives ``{"BENCH_SECONDS": ["0.41"]}``); of two lines with one first word, the later."""
    return {words[0]: words[1:] for words in map(str.split, text.splitlines())
            if words and words[0].startswith("BENCH")}


def median_seconds(fn, repeat: int) -> float:
    """Median wall seconds (``time.perf_counter``) of ``repeat`` calls of ``fn()``, in this process."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def best_seconds(fn, repeat: int = 3) -> float:
    """Least wall seconds (``time.perf_counter``) of ``repeat`` calls of ``fn()``, in this process."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def medians(runs: list, keys=None, peak=("rss_mb",)) -> dict:
    """The figures of several runs (dicts of figures, one a run) as one dict.

    For each key in ``keys`` (default: every key of the first run whose value is
    a number, but ``code``) the median over the runs; for each key in ``peak``
    the largest value instead (by default ``rss_mb``: the peak memory of several
    runs is the largest of their peaks; ``bench_stats.py`` passes ``peak=()``
    and reports the median peak RSS).
    """
    if keys is None:
        keys = [k for k, v in runs[0].items() if k != "code" and isinstance(v, (int, float))]
    out = {k: statistics.median(r[k] for r in runs) for k in keys}
    out.update({k: max(r[k] for r in runs) for k in peak})
    return out


def load_average() -> str:
    """The 1, 5 and 15 minute load averages, e.g. ``"0.3, 0.2, 0.4"``."""
    return ", ".join(f"{v:.1f}" for v in os.getloadavg())


def machine_line(numpy: bool = True, load: bool = False) -> str:
    """Where the figures come from, as one line: ``numpy 2.1.3, Python 3.11.7, 2 CPUs,
    x86_64`` (without numpy's version when ``numpy`` is false; ``load``: the load
    average appended, as ``, load average 0.3, 0.2, 0.4``)."""
    parts = []
    if numpy:
        import numpy as np

        parts.append(f"numpy {np.__version__}")
    parts += [f"Python {platform.python_version()}", f"{os.cpu_count()} CPUs", platform.machine()]
    if load:
        parts.append(f"load average {load_average()}")
    return ", ".join(parts)


def row(label: str, value: str, note: str = "") -> str:
    """One line of a benchmark's text table: label, value right-aligned, note."""
    return f"  {label:<44} {value:>12}  {note}".rstrip()
