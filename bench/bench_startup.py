"""Benchmark the CLI's start time: what a user waits for before any work is done.

Three commands, each in a fresh process (started by the harness's launcher),
runs of the three interleaved so that drift in the machine's load hits all of
them alike, medians of ``--repeat``:

* ``splatconv --help``: the group parses its options and lists the commands;
* ``splatconv info sample_data/dancers.ply``: a small file read and described
  (2,000 splats), so nearly all of it is start-up;
* ``python -c "import splatconv"``: the package's own import.

For each: wall seconds (interpreter start included) and CPU seconds (user +
system; steadier than wall seconds on a shared machine). The console script
beside the interpreter is used when there is one, else ``python -m splatconv``;
both import the package from ``PYTHONPATH`` first, so pointing ``PYTHONPATH``
at another checkout measures that one (the runs start in an empty folder:
``python -c`` would import a ``splatconv`` in the current folder first). The exit status is 0 whatever the
figures; it is a report, not a test.

Run::

    python bench/bench_startup.py [--repeat R]
"""

from __future__ import annotations

import argparse
import os

import _harness as h

SAMPLE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "sample_data", "dancers.ply")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15, help="fresh runs of each command (default 15)")
    args = parser.parse_args()

    cli = [h.CLI] if os.path.exists(h.CLI) else [h.PYTHON, "-m", "splatconv"]
    commands = {
        "splatconv --help": cli + ["--help"],
        "splatconv info sample_data/dancers.ply": cli + ["info", SAMPLE],
        'python -c "import splatconv"': [h.PYTHON, "-c", "import splatconv"],
    }
    runs = {label: [] for label in commands}
    here = os.getcwd()
    with h.work_folder() as folder:
        os.chdir(folder)
        try:
            for _ in range(args.repeat):
                for label, argv in commands.items():
                    runs[label].append(h.run_fresh(argv, stdout="discard", check=True))
        finally:
            os.chdir(here)

    print(f"CLI start time, medians of {args.repeat} fresh processes (wall / CPU seconds)")
    print(f"  {h.machine_line(numpy=False, load=True)}")
    for label, results in runs.items():
        m = h.medians(results, keys=("wall", "cpu"), peak=())
        print(h.row(label, f"{m['wall']:.3f} s", f"CPU {m['cpu']:.3f} s"))


if __name__ == "__main__":
    main()
