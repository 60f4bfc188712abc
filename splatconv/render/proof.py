"""What a compressed scene is proved by: the views a user will see it from, the times, and the worst frame.

``convert --min-psnr`` measures each candidate file against the scene it
encodes, and ``verify --proof-views`` draws the same frames, so the two agree:

* each header camera (the first :data:`MAX_CAMERAS`), as the file stores it;
* near it: orbited by :data:`NEAR_DEGREES` about the scene's centre, and
  stepped :data:`NEAR_STEP` of the way towards it (a user's first drag or wheel);
* the view splaTV opens every file at (:data:`SPLATV_VIEW`, its built-in
  camera's focal lengths), which may be far from any header camera;
* each header camera as splaTV's viewer shows it in its window
  (:data:`~splatconv.viewer.SPLATV_WINDOW`, the camera's focal lengths in
  pixels of the window: the middle of what it saw, at its own scale), and
  widened (:data:`WIDENED`: what lies just out of its frame);

each at :data:`PROOF_TIMES`, all :data:`PROOF_WIDTH` pixels wide: a camera's
whole view (near views too) with the first camera's aspect, the viewer's window
scaled down. Both, because a real scene pruned to 40 dB over the camera's whole
view drew the window's centre at 39.6 dB, and one pruned over the window alone
lost its subject, outside the window but in the camera's view (pruned over the
camera's view, it lost a person just below the frame: hence the widened view). Both scenes are
drawn as the viewer draws them (the ``.splatv`` texture a conversion holds).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import viewer
from ..viewer import SPLATV_FOCAL, SPLATV_VIEW, SPLATV_WINDOW
from ..cameras import camera_for_box
from ..files.paging import hand_back
from ..formats import format_for
from ..io import read
from ..model import Scene
from ..ops import prune
from ..progress import SILENT, Progress
from . import camera as cam
from . import diff as imgdiff
from .frames import Source
from .paths import drawn_box, orbited, stepped
from .preview import Renderer, View
from .sort import depth_keys

PROOF_TIMES = (0.1, 0.3, 0.5, 0.7, 0.9)
PROOF_WIDTH = 640
#: Splats a proof draws at most, over one scene's frames: a larger scene is proved from fewer
#: frames (:func:`proof_plan`), chosen first of all views and times, at least :data:`MIN_FRAMES`.
PROOF_SPLAT_FRAMES = 2_000_000
MIN_FRAMES = 2
#: The times a limited proof takes first.
TIME_PRIORITY = (0.5, 0.1, 0.9, 0.3, 0.7)
MAX_CAMERAS = 4
NEAR_DEGREES = 4.0
NEAR_STEP = 0.1
#: A camera's whole view drawn with its focal lengths scaled by this: what lies just out of its frame,
#: which a user sees on the first zoom out (and which ``--prune`` must not take for unseen).
WIDENED = 0.5
#: The most important splats :func:`ranked` puts last (one is the first record the viewer draws twice).
KEEP_IMPORTANT = 4


@dataclass
class Proof:
    """How a candidate scene draws against its source.

    Attributes
    ----------
    worst, mean : float
        PSNR in dB of the worst frame and the mean over frames (inf: identical).
    where : str
        The worst frame: its view's name and time.
    frames : int
        Frames compared.
    times : tuple of float
        The times drawn, at each view.
    values : tuple of float
        Each frame's PSNR, in the prover's frame order (NaN for a frame not drawn).
    complete : bool
        False where the proof stopped at a frame below its floor (:meth:`Prover.prove`):
        ``worst`` is then that frame's, below the floor but not always the least, and ``mean``
        is of the frames drawn.
    """

    worst: float
    mean: float
    where: str
    frames: int
    times: tuple
    values: tuple = ()
    complete: bool = True


def proof_views(scene: Scene, drawn: np.ndarray | None = None) -> list:
    """(name, View) pairs a proof draws ``scene`` from (see the module docstring).

    Parameters
    ----------
    scene : Scene
        Its cameras (a framing camera when it has none) and its drawable splats'
        centre (the middle of their 2nd..98th percentile box) place the near views.
    drawn : (N,) bool ndarray, optional
        ``~viewer.undrawable(scene.columns)``, where the caller has it.
    """
    cameras = list((scene.cameras or [])[:MAX_CAMERAS])
    lo, hi = drawn_box(scene, drawn)
    centre = (lo + hi) / 2
    if not cameras:
        cameras = [camera_for_box(lo, hi)]
    first = cameras[0]
    size = (PROOF_WIDTH, max(1, round(PROOF_WIDTH * int(first["height"]) / int(first["width"]))))
    # splaTV's window: focal lengths are pixels of the window, whose frame is drawn scaled.
    window = (PROOF_WIDTH, max(1, round(PROOF_WIDTH * SPLATV_WINDOW[1] / SPLATV_WINDOW[0])))
    scale = window[0] / SPLATV_WINDOW[0]
    views = []
    for i, camera in enumerate(cameras):
        for name, c in ((f"camera {i}", camera), (f"camera {i} orbited {NEAR_DEGREES:g} deg",
                                                    orbited(camera, centre, NEAR_DEGREES)),
                        (f"camera {i} stepped in", stepped(camera, centre, NEAR_STEP))):
            w, h, fx, fy = cam.fit(c, size)
            views.append((name, View(cam.view_matrix(c), fx, fy, w, h)))
        views.append((f"camera {i} in splaTV's window", View(cam.view_matrix(camera), float(camera["fx"]) * scale,
                                                               float(camera["fy"]) * scale, *window)))
        w, h, fx, fy = cam.fit(camera, size)
        views.append((f"camera {i} widened", View(cam.view_matrix(camera), fx * WIDENED, fy * WIDENED, w, h)))
    views.append(("splaTV's opening view", View(list(SPLATV_VIEW), SPLATV_FOCAL[0] * scale,
                                                SPLATV_FOCAL[1] * scale, *window)))
    return views


def proof_plan(scene: Scene, views: list | None = None) -> tuple:
    """The views and times a proof of ``scene`` draws: ``(views, times)``.

    Every view of :func:`proof_views` (or ``views``) at every one of
    :data:`PROOF_TIMES`, unless that draws more than :data:`PROOF_SPLAT_FRAMES`
    splats (the scene's count per frame); then as many frames as that allows
    (at least :data:`MIN_FRAMES`), about as many views as times: the first
    camera's whole view and splaTV's window of it, splaTV's opening view, then
    the first camera's near views and the other cameras; the times of
    :data:`TIME_PRIORITY`, in time order.
    """
    views = proof_views(scene) if views is None else views
    times = list(PROOF_TIMES)
    allowed = max(MIN_FRAMES, PROOF_SPLAT_FRAMES // max(1, scene.count))
    if len(views) * len(times) <= allowed:
        return views, tuple(times)
    per_time = max(1, min(len(times), math.isqrt(allowed)))
    # The first camera, as the viewer's window shows it, the opening view, then the rest in order.
    firsts = sorted(range(len(views)), key=lambda i: (i != 0, i != 3, i != len(views) - 1, i))
    chosen = sorted(firsts[:max(1, min(len(views), allowed // per_time))])
    prior = [t for t in TIME_PRIORITY if t in times] + [t for t in times if t not in TIME_PRIORITY]
    return [views[i] for i in chosen], tuple(sorted(prior[:per_time]))


class Prover:
    """A proof's source frames, drawn once, against which each candidate is drawn and compared.

    Parameters
    ----------
    source : Scene
    views, times
        From :func:`proof_plan` (one size).
    """

    def __init__(self, source: Scene, views: list, times, *, progress: Progress = SILENT):
        self.views, self.times = views, tuple(times)
        first = views[0][1]
        self.renderer = Renderer(first.width, first.height)
        self.frames = []
        try:
            Source("<source>", source).load_into(self.renderer)
            hand_back(source.columns.values())  # a mapped input's pages: the texture holds what is drawn
            with progress.stage("drawing", len(views) * len(self.times), "frame") as advance:
                for _name, view in views:
                    for t in self.times:
                        self.frames.append(self.renderer.draw(view, float(t)))
                        advance()
            self.renderer.unload()
        except BaseException:
            self.close()
            raise

    def prove(self, candidate, *, floor: float | None = None, first=None, progress: Progress = SILENT) -> Proof:
        """Draw ``candidate`` from each view at each time, as the viewer draws it, against the source.

        ``candidate``: a Scene, or the path of a file, read back as any reader would
        (:func:`load_candidate`). With ``floor``, the proof stops at the first frame
        below it (a candidate that breaks a floor is known to from one frame), drawing
        the frames in the order ``first`` gives (indices into :attr:`Proof.values`; the
        worst frames of a like candidate first, where a failure shows soonest).
        """
        if isinstance(candidate, Scene):
            Source("<candidate>", candidate).load_into(self.renderer)
        else:
            load_candidate(self.renderer, candidate)
        plan = [(name, view, t) for name, view in self.views for t in self.times]
        order = range(len(plan)) if first is None else first
        values = np.full(len(plan), np.nan)
        drawn = []
        with progress.stage("drawing", len(self.frames), "frame") as advance:
            for i in order:
                name, view, t = plan[i]
                values[i] = imgdiff.psnr(self.frames[i], self.renderer.draw(view, float(t)))
                drawn.append(i)
                advance()
                if floor is not None and values[i] < floor:
                    break
        self.renderer.unload()
        complete = len(drawn) == len(plan)
        drawn = np.sort(drawn)  # the worst of equals is the first in frame order, as without ``first``
        worst = int(drawn[np.argmin(values[drawn])])
        finite = values[drawn][np.isfinite(values[drawn])]  # identical frames (inf) are left out of the mean
        mean = float(finite.mean()) if len(finite) else float("inf")
        name, _view, t = plan[worst]
        return Proof(float(values[worst]), mean, f"{name} at t={t:g}", len(drawn), self.times,
                     tuple(float(v) for v in values), complete)

    def close(self) -> None:
        if self.renderer is not None:
            self.renderer.release()
            self.renderer = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def prove(source: Scene, candidate: Scene, views: list, times=None, *, progress: Progress = SILENT) -> Proof:
    """Draw ``source`` and ``candidate`` from each view at each time, as the viewer draws them, and compare.

    Parameters
    ----------
    source, candidate : Scene
    views : list of (str, View)
        From :func:`proof_views` or :func:`proof_plan` (one size).
    times : sequence of float, optional
        Default :data:`PROOF_TIMES`.
    """
    with Prover(source, views, PROOF_TIMES if times is None else times, progress=progress) as prover:
        return prover.prove(candidate, progress=progress)


def load_candidate(renderer: Renderer, path) -> None:
    """Load into ``renderer`` what a proof draws of the file ``path``, read back as any reader would.

    The texture a conversion of it to the texture format holds: where its format
    decodes to the texture's records (:attr:`~splatconv.formats.base.Format.converted_texture`),
    those records a block at a time, in that conversion's order, never the scene
    nor the whole texture in memory; else the scene read and packed.
    """
    fmt = format_for(path)
    count = fmt.splat_count(path) if fmt.converted_texture is not None else None
    if count is None:  # no records to decode, or a header the reader refuses (and says why)
        Source(str(path), read(path)).load_into(renderer)
        return
    renderer.load_pieces(count, lambda put: fmt.converted_texture(path, put))


def frame_weights(scene: Scene, views: list, times=None, drawable: np.ndarray | None = None) -> np.ndarray:
    """What each splat of ``scene`` adds to the frames drawn from ``views`` at ``times``, in units of what the
    median splat that shows adds: ``(N,) float64``, 0 for a splat no frame shows.

    :func:`splatconv.ops.prune.contributions` from ``views`` (:func:`proof_views`)
    at ``times`` (default :data:`PROOF_TIMES`), each splat's opacity at a time the
    best between it and the next: a splat seen only between two proved times counts.
    Relative to the scene's median, so that a splat keeps its weight in the scene
    with the least of them left out (``--prune``).
    """
    matrices = [(view.matrix, cam.projection_matrix(view.fx, view.fy, view.width, view.height), view.width,
                 view.height) for _name, view in views]
    score = prune.contributions(scene.columns, matrices, PROOF_TIMES if times is None else times, drawable)
    shown = score[score > 0]
    return score / np.median(shown) if len(shown) else score


def ranked(scene: Scene, views: list, times=None, weights: np.ndarray | None = None,
           drawable: np.ndarray | None = None) -> np.ndarray:
    """The drawable splats of ``scene``, least first by what they add to the proof's frames: ``(M,) intp``.

    By :func:`frame_weights` (``weights``, where computed already; ``drawable``, its
    drawable rows, where known).
    Last of all come the splats the viewer's sort depends on
    (:func:`splatconv.render.sort.viewer_order`): it scales the depth keys by
    their range, never draws a splat whose scaled key reaches the top (the
    farthest, or none as the rounding falls), and draws the first record once
    more in its place. Leaving out the nearest or the farthest from a view changes
    the range, so another splat may go undrawn and the first record drawn twice
    (on a real scene, 40 dB to 18). So the nearest and farthest from each view,
    the first drawable row and the :data:`KEEP_IMPORTANT` most important (the
    first record in importance order, its quantized key allowing) come last.
    """
    score = frame_weights(scene, views, times, drawable) if weights is None else weights
    order = prune.ranked(scene.columns, score, drawable)
    xyz = np.stack([np.asarray(scene.columns[a])[order] for a in "xyz"], axis=1)
    apart = np.zeros(len(order), bool)
    for _name, view in views:
        key = depth_keys(xyz, view.view_proj())
        if len(key):  # one of each extreme keeps the range
            apart[[np.argmax(key), np.argmin(key)]] = True
    apart[order == order.min(initial=0)] = True
    importance = np.nan_to_num(viewer.importance({k: np.asarray(v)[order] for k, v in scene.columns.items()}),
                               nan=-np.inf)
    apart[viewer.importance_order(importance)[:KEEP_IMPORTANT]] = True
    return np.concatenate([order[~apart], order[apart]])
