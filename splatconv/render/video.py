"""Write drawn frames as a video, one frame at a time: H.264 in ``.mp4``, VP9 in ``.webm``.

The encoders are FFmpeg's (libx264, libvpx), reached through PyAV (the ``av``
package, the optional ``video`` extra: ``pip install 'splatconv[video]'``),
which is imported only when a video is written. Frames are converted from the
framebuffer's RGB to BT.709 limited-range 4:2:0 and tagged so, as players
expect of HD video; 4:2:0 needs an even width and height.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from ..errors import SplatconvError, UsageError

#: Frames a second of a video when not told: film's rate, so that ``--frames 24`` is one second.
DEFAULT_FPS = 24.0
#: The rates a video may play at.
FPS_RANGE = (1.0, 240.0)
INSTALL_HINT = "pip install 'splatconv[video]' (PyAV, FFmpeg's encoders)"


@dataclass(frozen=True)
class Codec:
    """How one video container is written.

    Attributes
    ----------
    container : str
        FFmpeg's name for the container (muxer).
    encoder : str
        FFmpeg's encoder.
    name : str
        The codec in words, for the summary.
    options : dict
        Encoder options: quality chosen so that a frame decodes well above 30 dB PSNR.
    """

    container: str
    encoder: str
    name: str
    options: dict = field(default_factory=dict)


#: Video outputs by suffix. x264 runs on one thread: on several it encoded the same small frames
#: differently from run to run (one thread encodes 640x360 at about 70 frames a second, faster
#: than llvmpipe draws them).
CODECS = {
    ".mp4": Codec("mp4", "libx264", "H.264", {"crf": "18", "threads": "1"}),
    # Constant quality (crf with no bitrate cap); row-mt lets libvpx use more than one core.
    ".webm": Codec("webm", "libvpx-vp9", "VP9", {"crf": "24", "b": "0", "row-mt": "1"}),
}
#: Container options: no random ids or library version in the file (the same frames, the same bytes).
_CONTAINER_OPTIONS = {"fflags": "+bitexact"}
VIDEO = tuple(CODECS)


class VideoUnavailable(SplatconvError):
    """No encoder for the video asked for: PyAV is not installed, or its FFmpeg lacks the encoder."""


def _av():
    try:
        import av
    except ImportError as e:
        raise VideoUnavailable(f"writing video needs PyAV ({e}); {INSTALL_HINT}") from None
    return av


def check_video(suffix: str, width: int | None = None, height: int | None = None, fps: float = DEFAULT_FPS) -> Codec:
    """The :class:`Codec` for ``suffix``, once PyAV and the encoder are found; checks the size and rate.

    Raises
    ------
    VideoUnavailable
        PyAV is not installed, or its FFmpeg has no such encoder (exit 1).
    UsageError
        An odd ``width`` or ``height`` (4:2:0 halves both), or ``fps`` outside :data:`FPS_RANGE`.
    """
    codec = CODECS[suffix.lower()]
    if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:
        raise UsageError(f"--fps: expected {FPS_RANGE[0]:g} to {FPS_RANGE[1]:g}, got {fps:g}")
    if width is not None and (width % 2 or height % 2):
        raise UsageError(f"--size: {width}x{height}: a {suffix} video needs an even width and height "
                         f"(4:2:0 colour halves both)")
    av = _av()
    try:
        av.codec.Codec(codec.encoder, "w")
    except Exception:  # PyAV raises its own UnknownCodecError or a ValueError, by version
        raise VideoUnavailable(f"this PyAV's FFmpeg has no {codec.encoder} encoder for {codec.name}; "
                               f"{INSTALL_HINT}") from None
    return codec


def even_size(width: int, height: int) -> tuple:
    """``(width, height)`` each rounded down to even (2 at least): the size a 4:2:0 video can hold."""
    return max(2, width - width % 2), max(2, height - height % 2)


def write_video(frames, stream, suffix: str, fps: float = DEFAULT_FPS) -> int:
    """Encode frames as they come into a video written to ``stream``; no frame is kept here.

    Parameters
    ----------
    frames : iterable of (H, W, 3+) uint8 ndarray
        RGB (and alpha, left out: the framebuffer is premultiplied over black), all
        one even size.
    stream : binary file object
        Seekable (the ``.mp4`` index is written at the end).
    suffix : str
        ``.mp4`` or ``.webm`` (:data:`CODECS`).
    fps : float

    Returns
    -------
    int
        Frames written.
    """
    codec = check_video(suffix, fps=fps)
    av = _av()
    container = av.open(stream, mode="w", format=codec.container, options=dict(_CONTAINER_OPTIONS))
    count = 0
    try:
        video = None
        for frame in frames:
            height, width = frame.shape[:2]
            if video is None:
                check_video(suffix, width, height, fps)
                video = container.add_stream(codec.encoder, rate=Fraction(fps).limit_denominator(1001),
                                             options=dict(codec.options))
                video.width, video.height, video.pix_fmt = width, height, "yuv420p"
                _tag_bt709(video.codec_context)
            picture = av.VideoFrame.from_ndarray(np.ascontiguousarray(frame[:, :, :3]), format="rgb24")
            picture = picture.reformat(format="yuv420p", dst_colorspace="ITU709", dst_color_range="MPEG")
            picture.pts = count
            container.mux(video.encode(picture))
            count += 1
        if video is not None:
            container.mux(video.encode(None))  # flush the frames the encoder holds back
    finally:
        container.close()
    return count


def _tag_bt709(context) -> None:
    """Say in the stream what the frames hold (BT.709, limited range) so that players convert them back so."""
    context.colorspace = 1  # AVCOL_SPC_BT709
    context.color_range = 1  # AVCOL_RANGE_MPEG
    for name in ("color_primaries", "color_trc"):  # PyAV 13 and later
        if hasattr(context, name):
            setattr(context, name, 1)  # BT.709
