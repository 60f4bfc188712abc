"""Shared helpers: build small splat files of every flavour in tmp_path (scenes from :mod:`tests.scenes`)."""

from __future__ import annotations

import contextlib
import signal

import numpy as np
import plyfile
import pytest

from splatconv import model
from splatconv.formats import ply

from .scenes import gs_columns, random_columns

# Tests send SIGINT to the commands they start. A suite started with SIGINT ignored (a background
# job of a non-interactive shell) would pass that on to every child, which then never sees it.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

GS_PROPS = ("x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2") + tuple(
    f"f_rest_{i}" for i in range(45)) + ("opacity", "scale_0", "scale_1", "scale_2",
                                         "rot_0", "rot_1", "rot_2", "rot_3")


def write_ply(path, columns: dict, *, text=False, byte_order="<", dtype="f4", order=None,
              extra_props=(), extra_elements=(), comments=(), obj_info=()):
    """Write a PLY with plyfile: any encoding, property order and extras."""
    names = list(order or columns)
    n = len(next(iter(columns.values())))
    fields = [(name, dtype) for name in names] + [(name, "f4") for name in extra_props]
    arr = np.zeros(n, dtype=fields)
    for name in names:
        arr[name] = columns[name]
    for i, name in enumerate(extra_props):
        arr[name] = i + 0.5
    elements = [plyfile.PlyElement.describe(arr, "vertex")] + list(extra_elements)
    plyfile.PlyData(elements, text=text, byte_order=byte_order, comments=list(comments),
                    obj_info=list(obj_info)).write(str(path))
    return path


def lite_columns_with_normals(cols: dict) -> dict:
    out = {}
    for name in ply.LITE_LAYOUT:
        out[name] = cols[name] if name in cols else np.zeros(len(cols["x"]), np.float32)
    return out


@pytest.fixture
def lite_ply(tmp_path):
    """A 3000-splat lite PLY in the exact SpacetimeGaussians layout."""
    cols = random_columns(3000)
    return write_ply(tmp_path / "scene.ply", lite_columns_with_normals(cols))


@pytest.fixture
def gs_ply(tmp_path):
    """A 500-splat plain 3DGS PLY with f_rest_*."""
    return write_ply(tmp_path / "gs.ply", gs_columns(500, GS_PROPS))


def splatv_bytes(records: np.ndarray, cameras=None, *, pad=True, chunks=None) -> bytes:
    """A .splatv file around raw (N, 16) uint32 records."""
    import json

    from splatconv.formats import splatv

    n = len(records)
    h = splatv.texture_height(n)
    data = np.zeros((h * 1024, 16), "<u4")
    data[:n] = records
    body = data.tobytes() if pad else np.ascontiguousarray(records, "<u4").tobytes()
    chunk = {"type": "splat", "size": 4096 * h * 16, "texwidth": 4096, "texheight": h,
             "cameras": cameras if cameras is not None else []}
    text = json.dumps(chunks if chunks is not None else [chunk]).encode()
    return np.array([0x674B, len(text)], "<u4").tobytes() + text + body


__all__ = ["random_columns", "write_ply", "splatv_bytes", "model"]


@pytest.fixture(scope="module")
def renderer():
    """A float-reference renderer the size of :data:`tests.scenes.CAMERA`, one a test module."""
    from splatconv.render.preview import Renderer

    from .scenes import H, W

    r = Renderer(W, H)
    yield r
    r.release()


@pytest.fixture(scope="session")
def sample_splatv(tmp_path_factory):
    """The bundled sample scene converted to .splatv with its cameras (made once per run)."""
    from pathlib import Path

    import splatconv

    root = Path(__file__).resolve().parent.parent
    out = tmp_path_factory.mktemp("sample") / "dancers.splatv"
    splatconv.convert(root / "sample_data/dancers.ply", out, cameras=root / "sample_data/cameras.json")
    return out


@pytest.fixture(scope="session")
def _chromium():
    """One headless Chromium for the whole run (see :func:`tests.web_support.launched`): starting one costs
    seconds, and every page test opens its own context anyway."""
    from .web_support import launched

    with launched() as b:
        yield b


@pytest.fixture
def browser(_chromium):
    """The session's Chromium for one test; whatever pages and contexts the test leaves open are closed after it,
    so no test sees another's (or pays for its animation)."""
    before = set(_chromium.contexts)
    yield _chromium
    for context in _chromium.contexts:
        if context not in before:
            context.close()


class ProgressRecorder:
    """A :class:`splatconv.progress.Progress` that records each stage as [label, total, unit, done]."""

    def __init__(self):
        self.stages = []

    def stage(self, label, total=None, unit="it"):
        entry = [label, total, unit, 0]
        self.stages.append(entry)

        def advance(n=1):
            entry[3] += n

        return contextlib.nullcontext(advance)


@pytest.fixture(autouse=True)
def _small_proofs(monkeypatch):
    """A .splatvq convert proves its file by drawing it: in tests, the same views at a test's size and two
    times (tests/test_splatvq_proof.py and the real-scene tests check the frames themselves)."""
    from splatconv.render import proof

    monkeypatch.setattr(proof, "PROOF_WIDTH", 160)
    monkeypatch.setattr(proof, "PROOF_TIMES", (0.2, 0.8))
