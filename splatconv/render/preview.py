"""Draw frames of a scene with splaTV's shader, headless.

Two inputs are supported by one renderer:

* the ``.splatv`` texture as stored (RGBA32UI, halves and bytes): what the viewer
  shows of a converted file;
* the float reference path: the same shader maths fed float32 attributes with no
  half or 8-bit quantization, for measuring what a conversion loses.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from importlib import resources

import numpy as np

from ..viewer import SPLATS_PER_ROW, TEXWIDTH, WORDS_PER_SPLAT
from . import camera as cam
from .gl import create_context
from .layout import FLOAT_SPLATS_PER_ROW, FLOAT_WORDS
from .sort import viewer_order

#: Splats drawn by one draw call (:meth:`Renderer.draw`): the element buffer's, its two triangles each.
DRAW_CHUNK = 65536
#: Splat indices a row of the draw order texture: ``splat_indexed.glsl`` reads it with ``& 4095`` and ``>> 12``.
ORDER_ROW = 4096


def shader_source(name: str) -> str:
    """Text of a GLSL file shipped in ``splatconv/render/shaders``."""
    return resources.files(__package__).joinpath("shaders", name).read_text(encoding="utf-8")


def vertex_source(path: str) -> str:
    """The vertex shader for ``path`` ``"texture"`` (the stored, quantized texture) or ``"float"``.

    The viewer's program, its inputs worked out from the vertex's number
    (``splat_indexed.glsl``), not given per instance as the page does: see :meth:`Renderer.draw`.
    """
    fetch = {"texture": "fetch_splatv.glsl", "float": "fetch_float.glsl"}[path]
    return "\n".join(shader_source(n) for n in ("splat_head.glsl", "splat_indexed.glsl", fetch, "splat_main.glsl"))


@dataclass
class View:
    """Where a frame is seen from: a column-major view matrix and intrinsics."""

    matrix: list
    fx: float
    fy: float
    width: int
    height: int

    def view_proj(self) -> list:
        return cam.multiply(cam.projection_matrix(self.fx, self.fy, self.width, self.height), self.matrix)


@dataclass
class FrameTimes:
    """Seconds spent per stage of one frame."""

    sort: float = 0.0
    upload: float = 0.0
    draw: float = 0.0
    extra: dict = field(default_factory=dict)


class Renderer:
    """Draws splat frames into an offscreen RGBA8 framebuffer.

    Parameters
    ----------
    width, height : int
        Framebuffer size in pixels.
    ctx : moderngl.Context, optional
        Made with :func:`splatconv.render.gl.create_context` when omitted.
    """

    def __init__(self, width: int, height: int, ctx=None):
        import moderngl

        self._mgl = moderngl
        self._own_ctx = ctx is None
        self.ctx = ctx or create_context()
        frag = shader_source("splat.frag")
        self._programs = {p: self.ctx.program(vertex_shader=vertex_source(p), fragment_shader=frag)
                          for p in ("texture", "float")}
        self._chunk = DRAW_CHUNK  # the splats the element buffer holds, each draw call's
        corners = np.arange(self._chunk, dtype=np.uint32)[:, None] * 4 + np.array([0, 1, 2, 0, 2, 3], np.uint32)
        self._elements = self.ctx.buffer(corners.tobytes())
        self._order = None  # the draw order texture, ORDER_ROW indices a row
        self._texture = None
        self._path = None
        self._positions = None
        #: The texture record drawn for each splat index (None: the index itself): see :meth:`load_pieces`.
        self._record_of = None
        #: The draw order of the last frame (splat indices, front to back).
        self.last_order = None
        self.fbo = None
        self._resize(width, height)

    def _resize(self, width: int, height: int) -> None:
        if self.fbo is not None:
            self.ctx.detect_framebuffer(0).use()  # see release()
            for attachment in self.fbo.color_attachments:
                attachment.release()
            self.fbo.release()
        self.width, self.height = width, height
        self.fbo = self.ctx.framebuffer(color_attachments=[self.ctx.renderbuffer((width, height), 4)])

    def load(self, data: np.ndarray) -> float:
        """Upload what to draw, by its dtype; returns seconds.

        ``(R, 16) uint32`` is a ``.splatv`` texture (:meth:`load_records`),
        ``(R, FLOAT_WORDS) float32`` float reference rows (:meth:`load_float`).
        """
        if data.dtype == np.uint32 and data.shape[1:] == (WORDS_PER_SPLAT,):
            return self.load_records(data)
        if data.dtype == np.float32 and data.shape[1:] == (FLOAT_WORDS,):
            return self.load_float(data)
        raise TypeError(f"cannot draw a {data.dtype} array of shape {data.shape}")

    def load_records(self, records: np.ndarray) -> float:
        """Upload a ``.splatv`` texture, ``(texheight * 1024, 16) uint32``; returns seconds.

        Every record is drawn, padding included, as the viewer does. The array is
        not kept (only a copy of the positions, for the depth sort).
        """
        t0 = _time.perf_counter()
        records = np.ascontiguousarray(records, dtype="<u4")
        rows = len(records) // SPLATS_PER_ROW
        self._set_texture((TEXWIDTH, rows), records, "u4")
        self._positions = records[:, 0:3].view(np.float32).copy()
        self._record_of = None
        self._path = "texture"
        return _time.perf_counter() - t0

    def load_pieces(self, count: int, fill) -> float:
        """Upload a ``.splatv`` texture of ``count`` records a piece at a time, never held whole; returns seconds.

        ``fill(put)`` calls ``put(records)`` with the records in order, ``(M, 16)
        uint32`` pieces, until all ``count`` are given, and returns None or
        ``order``, ``(count,) intp``. The frames are then those :meth:`load_records`
        draws of ``records`` (None) or of ``records[order]``, zero padded to whole
        rows, either way: the depth sort reads the positions in that order, and each
        index drawn is mapped to the record that holds it, so the copy is never made.
        """
        t0 = _time.perf_counter()
        rows = max(1, -(-count // SPLATS_PER_ROW))
        total = rows * SPLATS_PER_ROW
        self._set_texture((TEXWIDTH, rows), None, "u4")
        positions = np.zeros((total, 3), dtype=np.float32)  # a padding record sits at the origin
        state = {"at": 0, "tail": np.empty((0, WORDS_PER_SPLAT), dtype="<u4")}  # records given; a partial row

        def write(records: np.ndarray) -> None:  # whole rows from state["at"] - len(tail) on
            first = (state["at"] - len(records)) // SPLATS_PER_ROW
            self._texture.write(memoryview(records).cast("B"),
                                viewport=(0, first, TEXWIDTH, len(records) // SPLATS_PER_ROW))

        def put(records: np.ndarray) -> None:
            records = np.asarray(records, dtype="<u4")
            start = state["at"]
            if start + len(records) > count:
                raise ValueError(f"more than the {count} records of the texture given")
            positions[start:start + len(records)] = records[:, 0:3].view(np.float32)
            state["at"] = start + len(records)
            joined = np.concatenate([state["tail"], records]) if len(state["tail"]) else records
            whole = len(joined) - state["at"] % SPLATS_PER_ROW
            if whole:
                write(np.ascontiguousarray(joined[:whole]) if whole < len(joined) else np.ascontiguousarray(joined))
            state["tail"] = joined[whole:].copy()

        order = fill(put)
        if state["at"] != count:
            raise ValueError(f"{state['at']} of the {count} records of the texture given")
        if len(state["tail"]) or count == 0:  # the last row: its padding is zero records
            last = np.zeros((SPLATS_PER_ROW, WORDS_PER_SPLAT), dtype="<u4")
            last[:len(state["tail"])] = state["tail"]
            state["at"] = total
            write(last)
        self._record_of = None
        if order is not None:
            order = np.asarray(order)
            positions[:count] = positions[:count][order]
            self._record_of = np.arange(total, dtype=np.int32)
            self._record_of[:count] = order
        self._positions = positions
        self._path = "texture"
        return _time.perf_counter() - t0

    def load_float(self, texels: np.ndarray) -> float:
        """Upload float reference rows from :func:`splatconv.render.layout.float_attributes`; returns seconds.

        Every row is drawn (pad with zero rows to draw what the ``.splatv``
        texture's padding adds). The array is not kept.
        """
        t0 = _time.perf_counter()
        n = len(texels)
        rows = max(1, -(-n // FLOAT_SPLATS_PER_ROW))
        if n == rows * FLOAT_SPLATS_PER_ROW and texels.dtype == np.dtype("<f4") and texels.flags.c_contiguous:
            padded = texels  # whole rows already: upload without a copy
        else:
            padded = np.zeros((rows * FLOAT_SPLATS_PER_ROW, FLOAT_WORDS), dtype="<f4")
            padded[:n] = texels
        self._set_texture((TEXWIDTH, rows), padded, "f4")
        self._positions = np.ascontiguousarray(texels[:, 0:3], dtype=np.float32)
        self._record_of = None
        self._path = "float"
        return _time.perf_counter() - t0

    def _set_texture(self, size, data, dtype):
        if self._texture is not None:
            self._texture.release()
        self._texture = self.ctx.texture(size, 4, None if data is None else memoryview(data).cast("B"), dtype=dtype)
        self._texture.filter = (self._mgl.NEAREST, self._mgl.NEAREST)
        self._texture.repeat_x = self._texture.repeat_y = False

    @property
    def positions(self) -> np.ndarray:
        """Positions of the loaded records, ``(R, 3) float32``: what the depth sort reads."""
        return self._positions

    def draw(self, view: View, time: float, times: FrameTimes | None = None,
             order: np.ndarray | None = None) -> np.ndarray:
        """Render one frame.

        Parameters
        ----------
        view : View
            Its width and height set the projection, the viewport uniform and the
            framebuffer size (the framebuffer is remade when they change).
        time : float
            Scene time (the viewer plays [0, 1]).
        times : FrameTimes, optional
            Filled with sort, upload and draw seconds.
        order : (R,) int32 ndarray, optional
            The draw order, when already known: ``viewer_order`` of the same
            positions and view (another renderer's :attr:`last_order`).

        Returns
        -------
        (H, W, 4) uint8 ndarray
            The framebuffer, top row first: premultiplied RGB and alpha.
        """
        if self._path is None:
            raise RuntimeError("nothing loaded")
        times = times if times is not None else FrameTimes()
        mgl = self._mgl
        if (view.width, view.height) != (self.width, self.height):
            self._resize(view.width, view.height)
        t0 = _time.perf_counter()
        order = viewer_order(self._positions, view.view_proj()) if order is None else order
        self.last_order = order
        t1 = _time.perf_counter()
        drawn = np.ascontiguousarray(order if self._record_of is None else self._record_of[order], dtype=np.int32)
        rows = max(1, -(-len(drawn) // ORDER_ROW))
        if self._order is None or self._order.height != rows:
            if self._order is not None:
                self._order.release()
            self._order = self.ctx.texture((ORDER_ROW, rows), 1, dtype="i4")
            self._order.filter = (mgl.NEAREST, mgl.NEAREST)
        whole, rest = divmod(len(drawn), ORDER_ROW)
        if whole:
            self._order.write(memoryview(drawn[:whole * ORDER_ROW]).cast("B"), viewport=(0, 0, ORDER_ROW, whole))
        if rest:
            self._order.write(memoryview(drawn[whole * ORDER_ROW:]).cast("B"), viewport=(0, whole, rest, 1))
        prog = self._programs[self._path]
        vao = self.ctx.vertex_array(prog, [], index_buffer=self._elements, index_element_size=4)
        prog["projection"].write(np.array(cam.projection_matrix(view.fx, view.fy, view.width, view.height), "f4"))
        prog["view"].write(np.array(view.matrix, "f4"))
        prog["focal"].value = (view.fx, view.fy)
        prog["viewport"].value = (view.width, view.height)
        prog["time"].value = time
        self._texture.use(0)
        sampler = "u_texture" if self._path == "texture" else "u_ftexture"
        prog[sampler].value = 0
        self._order.use(1)
        prog["u_order"].value = 1
        self.ctx.finish()
        t2 = _time.perf_counter()
        self.fbo.use()
        self.ctx.viewport = (0, 0, self.width, self.height)
        self.ctx.disable(mgl.DEPTH_TEST | mgl.CULL_FACE)
        self.ctx.enable(mgl.BLEND)
        self.ctx.blend_func = (mgl.ONE_MINUS_DST_ALPHA, mgl.ONE, mgl.ONE_MINUS_DST_ALPHA, mgl.ONE)
        self.ctx.blend_equation = mgl.FUNC_ADD
        self.fbo.clear(0.0, 0.0, 0.0, 0.0)
        # Without instancing (llvmpipe draws each instance apart), a chunk of splats a call, in order;
        # each waited for: else llvmpipe holds the binned triangles of every chunk until the frame is
        # read (a 1M-splat proof peaked 190 MB higher), for 5-10% of the draw's time.
        for first in range(0, len(drawn), self._chunk):
            prog["u_first"].value = first
            vao.render(mgl.TRIANGLES, vertices=6 * min(self._chunk, len(drawn) - first))
            self.ctx.finish()
        data = self.fbo.read(components=4, alignment=1)
        t3 = _time.perf_counter()
        vao.release()
        times.sort, times.upload, times.draw = t1 - t0, t2 - t1, t3 - t2
        img = np.frombuffer(data, dtype=np.uint8).reshape(self.height, self.width, 4)
        return img[::-1].copy()

    def unload(self) -> None:
        """Let go of what was loaded, the texture's memory with it, until the next load.

        The driver keeps a texture bound to a draw until another is drawn with, even
        once it is deleted: a one-row texture of padding records (none drawn) is loaded
        and drawn in its place, a frame nobody reads.
        """
        self.load_records(np.zeros((SPLATS_PER_ROW, WORDS_PER_SPLAT), dtype="<u4"))
        self.draw(View(list(np.eye(4, dtype=np.float32).ravel()), 1.0, 1.0, self.width, self.height), 0.0)
        self._path = None

    def release(self) -> None:
        """Free GL objects (the context too, when this renderer made it)."""
        # Rebind the default framebuffer first: moderngl restores the last bound one
        # when it makes the next framebuffer, and a deleted one is a GL error.
        self.ctx.detect_framebuffer(0).use()
        for obj in (self._order, self._texture, self._elements, *self.fbo.color_attachments, self.fbo,
                    *self._programs.values()):
            if obj is not None:
                obj.release()
        if self._own_ctx:
            self.ctx.release()
