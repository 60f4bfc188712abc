"""Signalling NaNs (bits 0x7F800001...) in every column: no command may warn.

Widening such a float32 to float64 raises the "invalid" flag, which numpy turns
into a RuntimeWarning (an error under this suite's settings).
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

import splatconv
from splatconv import io
from splatconv.cli import main
from splatconv.formats import splatvq
from splatconv.formats.splatv_layout import COLOR_WORD
from splatconv.model import COLUMNS, MOTION, OMEGA, Scene

from .conftest import splatv_bytes


@pytest.fixture(scope="module")
def snan_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("snan")
    rng = np.random.default_rng(7)
    n = 200
    cols = {c: (rng.normal(size=n) * 0.3).astype(np.float32) for c in COLUMNS}
    cols["rot_0"][:] = 1
    cols["trbf_scale"][:] = 1.0
    for i, c in enumerate(COLUMNS):
        bits = cols[c].view(np.uint32)
        bits[:8] = 0x7F800001  # signalling NaN
        bits[8:16] = 0xFF800123  # negative signalling NaN with a payload
        # And rows where only this column holds one, so that no filter drops them all at once.
        bits[16 + 5 * i:19 + 5 * i] = 0x7F800001
        bits[19 + 5 * i:21 + 5 * i] = 0xFF800123
    io.write(Scene(columns=cols), folder / "s.ply")
    splatconv.convert(folder / "s.ply", folder / "s.splatv")
    # Signalling half floats (0x7C01, 0xFC01) in every half slot of some records: a
    # .splatv keeps NaN payloads when read, so they reach the maths as signalling float32s.
    rec = rng.integers(0, 2**32, (n, 16), dtype=np.uint64).astype("<u4")
    rec[:, 0:3] = np.float32(0.5).view(np.uint32)
    rec[:8, 3:] = 0x7C017C01
    rec[8:16, 3:] = 0xFC01FC01
    rec[:, COLOR_WORD] = 0xFF808080
    (folder / "h.splatv").write_bytes(splatv_bytes(rec))
    splatconv.convert(folder / "h.splatv", folder / "hb.ply")
    # Static files with signalling NaNs: a 3DGS PLY and a .splat of the scene's rest state.
    rest = {c: v.copy() for c, v in cols.items()}
    for c in MOTION + OMEGA:
        rest[c][:] = 0
    rest["trbf_center"][:] = 0.5
    rest["trbf_scale"][:] = np.inf
    io.write(Scene(columns=rest), folder / "rest.ply", layout="3dgs")
    io.write(Scene(columns=rest), folder / "rest.splat")
    return folder


@pytest.mark.parametrize("args", [
    ["info", "s.ply"], ["stats", "s.ply"], ["stats", "s.ply", "s.splatv"], ["info", "s.splatv"],
    ["render", "s.ply", "r.png", "--size", "64x36"], ["verify", "s.ply", "s.splatv", "--size", "64x36"],
    ["diff", "s.ply", "s.splatv", "--size", "64x36"], ["bake", "s.ply", "b.ply", "--time", "0.5"],
    ["convert", "s.ply", "e.splatv", "--drop-nonfinite", "--trim", "0.2,0.8", "--rotate", "x:90"],
    ["merge", "s.ply", "s.ply", "m.splatv"],
    ["info", "h.splatv"], ["stats", "h.splatv"], ["stats", "h.splatv", "hb.ply"], ["stats", "s.ply", "s.splatv"],
    ["bake", "h.splatv", "hb.splat", "--time", "0.5"], ["convert", "h.splatv", "h.html"],
    ["bake", "s.ply", "b.splat", "--time", "0.5"], ["convert", "s.ply", "e.splat", "--trim", "0.5,0.6"],
    ["convert", "s.ply", "s.splat", "--drop-nonfinite"], ["merge", "s.ply", "s.ply", "m.splatv", "--segments"],
    ["convert", "rest.ply", "r.splat"], ["convert", "rest.splat", "r3.ply"], ["stats", "rest.ply", "rest.splat"],
    ["convert", "h.splatv", "hr.splatv", "--drop-nonfinite", "--trim", "0.1,0.9", "--scale", "2"],
    # Frame sequences: the same splats (motion fitted) and different ones (counts differ).
    ["convert", "s.ply", "s.ply", "s.ply", "q.splatv"], ["convert", "s.ply", "rest.ply", "hb.ply", "q2.splatv"],
    # .splatvq: written (by stats too, at each setting), embedded in a page, compared.
    ["convert", "h.splatv", "h.splatvq"], ["convert", "s.ply", "s.splatvq"], ["stats", "s.ply"],
    ["convert", "h.splatv", "hq.html", "--quality", splatvq.QUALITIES[-1]], ["stats", "s.splatv", "s.splatvq"],
])
def test_no_command_warns_on_signalling_nans(snan_files, monkeypatch, args):
    monkeypatch.chdir(snan_files)
    result = CliRunner().invoke(main, args)
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    assert "Warning" not in result.output and "Traceback" not in result.output
