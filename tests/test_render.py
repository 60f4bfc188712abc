"""The renderer against a numpy reference of splaTV's shader maths, on llvmpipe.

Tiny scenes (one or two splats) are drawn at 64x48 and compared pixel by pixel
with an independent float64 implementation of the vertex and fragment stages,
front-to-back blending into an 8-bit framebuffer.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np
import pytest

from splatconv import packing, viewer
from splatconv.formats import splatv_engine
from splatconv.model import COLUMNS
from splatconv.render import camera as cam
from splatconv.render.gl import create_context
from splatconv.render import preview
from splatconv.render.frames import Source
from splatconv.render.preview import Renderer, View
from tests import reference
from tests.scenes import moving_scene
from splatconv.formats.base import WriteReport

W, H = 64, 48
FOCAL = 60.0
IDENTITY_AT_5 = cam.view_matrix({"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "position": [0, 0, -5]})


@pytest.fixture(scope="module")
def ctx():
    c = create_context()
    assert c.error == "GL_NO_ERROR"
    yield c
    assert c.error == "GL_NO_ERROR"
    c.release()


def splat(**kw) -> dict:
    """One splat's model columns; scale and trbf_scale given linear for readability."""
    v = {name: 0.0 for name in COLUMNS}
    # A slight turn about z: with cov2d[0][1] exactly 0 the viewer normalizes a zero vector
    # and the splat vanishes, so axis-aligned test splats would draw nothing.
    v.update(rot_0=1.0, rot_3=0.05, f_dc_0=1.0, f_dc_1=1.0, f_dc_2=1.0, opacity=10.0, trbf_center=0.5)
    lin = {"scale": (0.2, 0.17, 0.2), "trbf": 10.0}  # exactly round splats vanish in the viewer
    for k, val in kw.items():
        if k == "scale":
            lin["scale"] = val
        elif k == "trbf":
            lin["trbf"] = val
        else:
            v[k] = val
    for i in range(3):
        v[f"scale_{i}"] = math.log(lin["scale"][i])
    v["trbf_scale"] = math.log(lin["trbf"])
    return v


def records_of(splats) -> np.ndarray:
    cols = {name: np.array([s[name] for s in splats], np.float32) for name in COLUMNS}
    block = reference.pack_block(cols, False, WriteReport())
    recs = np.zeros((1024, 16), "<u4")
    recs[:len(block)] = block
    return recs


def decode(rec: np.ndarray) -> dict:
    """Shader inputs of one record, decoded exactly."""
    h = lambda w, hi=False: float(packing.half_to_float(np.array([(rec[w] >> (16 if hi else 0)) & 0xFFFF]))[0])  # noqa: E731
    return {
        "center": rec[0:3].view(np.float32).astype(np.float64),
        "rot": np.array([h(3), h(3, 1), h(4), h(4, 1)]),
        "scale": np.array([h(5), h(5, 1), h(6)]),
        "rgba": np.array([(rec[7] >> s) & 0xFF for s in (0, 8, 16, 24)], np.float64) / 255,
        "m": np.array([h(8), h(8, 1), h(9), h(9, 1), h(10), h(10, 1), h(11), h(11, 1), h(12)]),
        "omega": np.array([h(13), h(13, 1), h(14), h(14, 1)]),
        "trbf": np.array([h(15), h(15, 1)]),
    }


def mat(flat16) -> np.ndarray:
    return np.array(flat16, np.float64).reshape(4, 4).T  # column-major -> math


def glsl_mat3(*v) -> np.ndarray:
    return np.array(v, np.float64).reshape(3, 3).T  # GLSL fills columns


def vertex_stage(s: dict, view: View, t: float):
    """Everything splaTV's vertex shader computes for one splat, or None when culled."""
    dt = t - s["trbf"][0]
    top = math.exp(-((dt / s["trbf"][1]) ** 2))
    if top < 0.02:
        return None
    m = s["m"]
    tpos = m[0:3] * dt + m[3:6] * dt * dt + m[6:9] * dt ** 3
    V = mat(view.matrix)
    P = mat(cam.projection_matrix(view.fx, view.fy, view.width, view.height))
    c = V @ np.append(s["center"] + tpos, 1.0)
    pos = P @ c
    clip = 1.2 * pos[3]
    if pos[2] < -clip or abs(pos[0]) > clip or abs(pos[1]) > clip:
        return None
    r = s["rot"] + s["omega"] * dt
    r = r / math.sqrt(r @ r)
    S = np.diag(s["scale"])
    R = glsl_mat3(1 - 2 * (r[2] ** 2 + r[3] ** 2), 2 * (r[1] * r[2] - r[0] * r[3]), 2 * (r[1] * r[3] + r[0] * r[2]),
                  2 * (r[1] * r[2] + r[0] * r[3]), 1 - 2 * (r[1] ** 2 + r[3] ** 2), 2 * (r[2] * r[3] - r[0] * r[1]),
                  2 * (r[1] * r[3] - r[0] * r[2]), 2 * (r[2] * r[3] + r[0] * r[1]), 1 - 2 * (r[1] ** 2 + r[2] ** 2))
    M = S @ R
    Vrk = 4 * M.T @ M
    z = c[2]
    J = glsl_mat3(view.fx / z, 0, -(view.fx * c[0]) / z ** 2, 0, -view.fy / z, (view.fy * c[1]) / z ** 2, 0, 0, 0)
    T = V[:3, :3].T @ J
    cov = T.T @ Vrk @ T
    mid = (cov[0, 0] + cov[1, 1]) / 2
    radius = math.hypot((cov[0, 0] - cov[1, 1]) / 2, cov[1, 0])
    l1, l2 = mid + radius, mid - radius
    if l2 < 0:
        return None
    d = np.array([cov[1, 0], l1 - cov[0, 0]])
    if not np.linalg.norm(d) > 0:
        return None  # normalize(vec2(0)) is NaN: an exactly round footprint draws nothing
    d = d / np.linalg.norm(d)
    major = min(math.sqrt(2 * l1), 1024) * d
    minor = min(math.sqrt(2 * l2), 1024) * np.array([d[1], -d[0]])
    color = np.clip(pos[2] / pos[3] + 1, 0, 1) * np.array([1, 1, 1, top]) * s["rgba"]
    return pos[:2] / pos[3], major, minor, color, pos[2] / pos[3]


def js_int32(v: float) -> int:
    if not math.isfinite(v):
        return 0
    v = int(v) % 2**32  # int() truncates toward zero
    return v - 2**32 if v >= 2**31 else v


@pytest.mark.parametrize("values", [
    [0.7, -0.7, -0.0, 1e9, -1e9, 2.0**31 - 0.5, -2.0**31 + 0.5, 123456.9],  # truncation alone
    [2.0**31, -2.0**31 - 0.5, 5e9, -5e9, 2.0**40 + 3, 1.5],  # wrapped modulo 2^32
    [float("nan"), float("inf"), float("-inf"), 3.9, -3.9],  # 0 where not finite
])
def test_js_int32_matches_javascripts_x_or_0(values):
    assert viewer.js_int32(np.array(values)).tolist() == [js_int32(v) for v in values]


def reference_order(recs, view: View) -> list:
    """The viewer's worker sort, statement by statement, over every record."""
    vp = cam.multiply(cam.projection_matrix(view.fx, view.fy, view.width, view.height), view.matrix)
    pos = recs[:, 0:3].view(np.float32).astype(np.float64)
    keys = [js_int32((vp[2] * x + vp[6] * y + vp[10] * z) * 4096) for x, y, z in pos]
    lo, hi = min(keys), max(keys)
    inv = 65536 / (hi - lo) if hi != lo else math.inf
    buckets = [js_int32((k - lo) * inv) if inv != math.inf else 0 for k in keys]
    counts = [0] * 65536
    for b in buckets:
        if b < 65536:  # a typed-array write past the end is ignored
            counts[b] += 1
    starts = [0] * 65536
    for i in range(1, 65536):
        starts[i] = starts[i - 1] + counts[i - 1]
    order = [0] * len(keys)
    for i, b in enumerate(buckets):
        if b < 65536:
            order[starts[b]] = i
            starts[b] += 1
    return order


def reference_image(recs, view: View, t: float) -> np.ndarray:
    """float64 reference: rasterize each splat's quad, blend front to back in RGBA8."""
    vp = np.array([view.width, view.height], np.float64)
    ys, xs = np.mgrid[0:view.height, 0:view.width]
    ndc = np.stack([(xs + 0.5) / view.width * 2 - 1, (ys + 0.5) / view.height * 2 - 1], axis=-1)
    dst = np.zeros((view.height, view.width, 4))
    drawn = []
    for i in reference_order(recs, view):
        out = vertex_stage(decode(recs[i]), view, t) if recs[i].any() else None
        if out is not None:
            drawn.append(out)
    for center, major, minor, color, depth in drawn:
        A = np.stack([major / vp, minor / vp], axis=1)
        uv = (ndc - center) @ np.linalg.inv(A).T
        inside = (np.abs(uv) <= 2).all(axis=-1)
        a = -(uv ** 2).sum(axis=-1)
        B = np.where(inside & (a >= -4), np.exp(a) * color[3], 0.0)
        src = np.concatenate([B[..., None] * color[:3], B[..., None]], axis=-1)
        dst = np.round(np.clip(src * (1 - dst[..., 3:4]) + dst, 0, 1) * 255) / 255
    return (dst * 255).round().astype(np.uint8)[::-1]


def draw(ctx, splats, t=0.5, view=None):
    view = view or View(IDENTITY_AT_5, FOCAL, FOCAL, W, H)
    recs = records_of(splats)
    r = Renderer(W, H, ctx=ctx)
    try:
        r.load_records(recs)
        img = r.draw(view, t)
        assert ctx.error == "GL_NO_ERROR"
    finally:
        r.release()
    assert ctx.error == "GL_NO_ERROR"
    return img, reference_image(recs, view, t)


def assert_close(img, ref, *, max_err=4, mean_err=0.25):
    diff = np.abs(img.astype(int) - ref.astype(int))
    assert diff.max() <= max_err, f"max error {diff.max()}"
    assert diff.mean() <= mean_err, f"mean error {diff.mean()}"


def test_single_splat_centre_colour_and_alpha(ctx):
    img, ref = draw(ctx, [splat(f_dc_0=200 / 255, f_dc_1=100 / 255, f_dc_2=50 / 255, opacity=0.0)])
    assert_close(img, ref)
    centre = img[H // 2 - 1:H // 2 + 1, W // 2 - 1:W // 2 + 1].reshape(-1, 4).astype(int)
    # opacity logit 0 -> alpha byte 128; the centre pixels sit half a pixel off the peak.
    assert np.all(np.abs(centre[:, 3] - 128) <= 8)
    assert np.all(np.abs(centre[:, :3] - np.array([200, 100, 50]) * centre[:, 3:] / 255) <= 2)
    assert img[0, 0].tolist() == [0, 0, 0, 0]


def test_ellipse_extent_and_orientation(ctx):
    angle = math.radians(30)
    q = [math.cos(angle / 2), 0, 0, math.sin(angle / 2)]  # 30 degrees about z
    img, ref = draw(ctx, [splat(scale=(0.5, 0.08, 0.08), rot_0=q[0], rot_3=q[3])])
    assert_close(img, ref)
    a = img[..., 3].astype(float)
    ys, xs = np.nonzero(a > 10)
    cov = np.cov(np.stack([xs, ys]), aweights=a[ys, xs])
    evals, evecs = np.linalg.eigh(cov)
    major = evecs[:, 1]
    measured = math.degrees(math.atan2(major[1], major[0])) % 180
    assert abs(measured - 30) < 3  # image y points down, like world y with this camera
    assert math.sqrt(evals[1] / evals[0]) == pytest.approx(0.5 / 0.08, rel=0.25)


@pytest.mark.parametrize("t", [0.62, 0.3, 0.5 + 0.2 * 1.95, 0.5 + 0.2 * 2.0, 0.5 - 0.2 * 2.0])
def test_temporal_fade_and_cut(ctx, t):
    s = splat(trbf=0.2, opacity=20.0, scale=(0.6, 0.5, 0.5))
    img, ref = draw(ctx, [s], t=t)
    assert_close(img, ref)
    peak, _ = draw(ctx, [s], t=0.5)
    top = math.exp(-(((t - 0.5) / 0.2) ** 2))
    if top < 0.02:
        assert not img.any()  # cut below 0.02 temporal opacity
    else:
        # alpha scales with exp(-(dt/s)^2), for dt before and after the centre
        a, b = img[..., 3].astype(float), peak[..., 3].astype(float)
        assert a.sum() / b.sum() == pytest.approx(top, abs=0.01)


# Record 0 is a splat far behind the camera's view: the viewer's sort drops the
# farthest bucket and draws record 0 again in its place, so it must be harmless.
FAR = splat(z=50.0, x=100.0)


@pytest.mark.parametrize("front", ["red", "blue"])
def test_front_to_back_blending(ctx, front):
    red = splat(x=-0.15, f_dc_1=0.0, f_dc_2=0.0, opacity=1.0, z=0.0 if front == "red" else 1.0)
    blue = splat(x=0.15, f_dc_0=0.0, f_dc_1=0.0, opacity=1.0, z=1.0 if front == "red" else 0.0)
    img, ref = draw(ctx, [FAR, red, blue])
    assert_close(img, ref)
    swapped, _ = draw(ctx, [FAR, blue, red])
    assert np.abs(swapped.astype(int) - img.astype(int)).max() <= 1  # order comes from depth
    overlap = img[H // 2, W // 2].astype(int)
    assert (overlap[0] > overlap[2]) == (front == "red")


def test_viewer_sort_drops_the_farthest_and_repeats_record_0(ctx):
    red = splat(x=-0.15, f_dc_1=0.0, f_dc_2=0.0, opacity=1.0)
    blue = splat(x=0.15, f_dc_0=0.0, f_dc_1=0.0, opacity=1.0, z=1.0)
    img, ref = draw(ctx, [red, blue])
    assert_close(img, ref)
    assert img[..., 2].max() == 0  # blue, alone in the last bucket, is not drawn


def test_frustum_culling_uses_the_centre(ctx):
    # A big splat whose centre is past 1.2 w is dropped even though it would reach
    # the image; just inside, it is drawn.
    x_out = 1.25 * 5 * W / (2 * FOCAL)
    img, ref = draw(ctx, [splat(x=x_out, scale=(1.0, 0.9, 1.0))])
    assert not img.any() and not ref.any()
    img, ref = draw(ctx, [splat(x=1.15 * 5 * W / (2 * FOCAL), scale=(1.0, 0.9, 1.0))])
    assert img.any()
    assert_close(img, ref)


def test_motion_and_omega(ctx):
    s = splat(motion_0=1.0, motion_4=2.0, omega_3=2.0, scale=(0.4, 0.05, 0.05), trbf=2.0)
    for t in (0.2, 0.5, 0.8):
        img, ref = draw(ctx, [s], t=t)
        assert_close(img, ref)
    a = img[..., 3].astype(float)
    centre_x = (a.sum(axis=0) * np.arange(W)).sum() / a.sum()
    assert centre_x == pytest.approx(W / 2 + FOCAL * 0.3 / 5, abs=0.6)  # moved 0.3 along x


def test_padding_records_draw_nothing(ctx):
    for t in (0.0, 0.5):
        r = Renderer(W, H, ctx=ctx)
        try:
            r.load_records(np.zeros((1024, 16), "<u4"))
            img = r.draw(View(IDENTITY_AT_5, FOCAL, FOCAL, W, H), t)
        finally:
            r.release()
        assert not img.any()


def malloc_live() -> int:
    """Bytes malloc has handed out and not had back (glibc's mallinfo2): what the driver holds too."""
    import ctypes

    class Info(ctypes.Structure):
        _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                         "fsmblks", "uordblks", "fordblks", "keepcost")]

    mallinfo2 = ctypes.CDLL(None).mallinfo2
    mallinfo2.restype = Info
    info = mallinfo2()
    return info.uordblks + info.hblkhd


def test_an_unloaded_renderer_lets_go_of_its_texture(ctx):
    # A proof unloads its source once its frames are drawn, and each candidate once compared,
    # so that a candidate's encode and decode never sit beside a texture nobody draws. The
    # driver keeps a deleted texture while it is bound to the last draw: unload draws once more.
    scene = moving_scene(64 * 1024, seed=5)
    r = Renderer(W, H, ctx=ctx)
    try:
        view = View(cam.view_matrix(scene.cameras[0]), 60.0, 60.0, W, H)
        Source("<s>", scene).load_into(r)
        first = r.draw(view, 0.5)
        assert first[..., 3].any()
        before = malloc_live()
        r.unload()
        assert before - malloc_live() >= 64 * 1024 * 64  # the texture's 4 MiB, its positions besides
        with pytest.raises(RuntimeError, match="nothing loaded"):
            r.draw(view, 0.5)
        Source("<s>", scene).load_into(r)
        assert np.array_equal(r.draw(view, 0.5), first)
    finally:
        r.release()


def test_screen_axes_are_capped_at_1024_pixels_as_in_the_viewer(ctx):
    # A splat whose major screen axis would be about 3,960 pixels long is drawn with
    # 1,024: its quad ends 1,024 pixels from the centre and the falloff at d pixels is
    # exp(-(2d / 1024)^2). This cap is what bounds the fill cost of huge splats.
    wide = View(IDENTITY_AT_5, 1000.0, 1000.0, 2048, 8)
    s = splat(scale=(7.0, 0.02, 0.02), rot_0=1.0, rot_3=0.0005, opacity=10.0)
    img, ref = draw(ctx, [s], view=wide)
    assert_close(img, ref, max_err=6)  # float32 over a 2,048-pixel quad: a few edge pixels round apart
    alpha = img[3:5, :, 3].astype(float).mean(axis=0)
    centre = alpha[1023:1025].mean()
    for d, capped, uncapped in ((500, 0.385, 0.938), (1000, 0.022, 0.775)):
        ratio = alpha[[1024 - d - 1, 1024 + d]].mean() / centre
        assert ratio == pytest.approx(capped, abs=0.02), d
        assert abs(ratio - uncapped) > 0.3


@pytest.mark.parametrize("path", ["texture", "float", "pieces", "packed"])
def test_the_renderer_draws_what_the_viewers_instanced_draw_draws(ctx, monkeypatch, path):
    # The renderer draws without instances (splat_indexed.glsl), a chunk of splats a call;
    # the viewer and the page draw one instance a splat. Same pixels, bit for bit: over
    # several chunks (here 1,000 splats each) and rows of the draw order (4,096 each), from
    # the stored texture, the float reference rows, records given a piece at a time in
    # another order (each drawn index mapped to its record), and the scene packed into the
    # renderer a block at a time (here 640 records each: Source.load_into).
    monkeypatch.setattr(preview, "DRAW_CHUNK", 1000)
    monkeypatch.setattr(splatv_engine, "BLOCK", 640)
    scene = moving_scene(5000, seed=3)
    source = Source("<moving>", scene)
    fetch = "fetch_float.glsl" if path == "float" else "fetch_splatv.glsl"
    instanced = ctx.program(vertex_shader="\n".join(preview.shader_source(n) for n in (
        "splat_head.glsl", "splat_instanced.glsl", fetch, "splat_main.glsl")),
        fragment_shader=preview.shader_source("splat.frag"))
    quad = ctx.buffer(np.array([-2, -2, 2, -2, 2, 2, -2, 2], "f4").tobytes())
    camera = scene.cameras[0]
    views = [View(cam.view_matrix(camera), fx, fx, 96, 72) for fx in (80.0, 200.0)]
    r = Renderer(96, 72, ctx=ctx)
    records = source.texture()
    assert len(records) > 4096
    if path == "float":
        r.load_float(source.reference())
    elif path == "pieces":
        shuffled = np.random.default_rng(0).permutation(len(records))
        stored = records[np.argsort(shuffled)]  # the file's order: stored[shuffled] is the texture

        def fill(put):
            for at in range(0, len(stored), 700):
                put(stored[at:at + 700])
            return shuffled
        r.load_pieces(len(records), fill)
    elif path == "packed":
        source.load_into(r)
        assert np.array_equal(r.positions, records[:, :3].view(np.float32))
    else:
        r.load_records(records)
    try:
        for view in views:
            for t in (0.1, 0.5, 0.9):
                mine = r.draw(view, t)
                drawn = r.last_order if path != "pieces" else shuffled[r.last_order]
                index = ctx.buffer(drawn.astype(np.int32).tobytes())
                vao = ctx.vertex_array(instanced, [(quad, "2f", "position"), (index, "i/i", "index")])
                instanced["projection"].write(np.array(cam.projection_matrix(view.fx, view.fy, 96, 72), "f4"))
                instanced["view"].write(np.array(view.matrix, "f4"))
                instanced["focal"].value = (view.fx, view.fy)
                instanced["viewport"].value = (96, 72)
                instanced["time"].value = t
                r.fbo.use()  # the renderer's texture is still bound to unit 0, where both programs read
                r.fbo.clear(0.0, 0.0, 0.0, 0.0)
                vao.render(moderngl.TRIANGLE_FAN, vertices=4, instances=len(drawn))
                theirs = np.frombuffer(r.fbo.read(components=4, alignment=1), np.uint8).reshape(72, 96, 4)[::-1]
                vao.release()
                index.release()
                assert mine[..., 3].astype(bool).mean() > 0.2  # the scene fills the frame
                assert np.array_equal(mine, theirs), (view.fx, t)
    finally:
        r.release()
        quad.release()
        instanced.release()
