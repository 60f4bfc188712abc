"""splatconv: move 4D Gaussian-splatting scenes between training and viewing formats.

The library API::

    scene = splatconv.read("scene.ply")          # -> Scene (columnar model)
    report = splatconv.write(scene, "scene.splatv")
    scene, report = splatconv.convert("scene.ply", "scene.splatv", compat="splatv-js")
    print(report.notes)                          # every lossy step, in words
"""

from __future__ import annotations

from .errors import FormatError, OutputError, SplatconvError, UnsupportedError, UsageError
from .io import COLOR_MODES, COMPAT_MODES, SORT_MODES, read, write
from .jobs.convert import convert
from .model import Scene

__version__ = "0.1.0"

__all__ = ["read", "write", "convert", "Scene", "SplatconvError", "FormatError", "UnsupportedError",
           "OutputError", "UsageError", "COLOR_MODES", "COMPAT_MODES", "SORT_MODES", "__version__"]
