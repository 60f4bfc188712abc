"""splatconv: move 4D Gaussian-splatting scenes between training and viewing formats.

The library API::

    scene = splatconv.read("scene.ply")          # -> Scene (columnar model)
    report = splatconv.write(scene, "scene.splatv")
    scene, report = splatconv.convert("scene.ply", "scene.splatv", compat="splatv-js")
    print(report.notes)                          # every lossy step, in words
"""

from __future__ import annotations

import importlib

from .errors import FormatError, OutputError, SplatconvError, UnsupportedError, UsageError

__version__ = "0.1.0"

#: Names loaded on first use, and the module each comes from: ``import splatconv`` (which
#: every ``splatconv`` command runs first) loads neither numpy nor the formats.
_LAZY = {**dict.fromkeys(("read", "write", "COLOR_MODES", "COMPAT_MODES", "SORT_MODES"), "io"),
         "convert": "jobs.convert", "Scene": "model"}


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    globals()[name] = value  # found directly from now on
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))

__all__ = ["read", "write", "convert", "Scene", "SplatconvError", "FormatError", "UnsupportedError",
           "OutputError", "UsageError", "COLOR_MODES", "COMPAT_MODES", "SORT_MODES", "__version__"]
