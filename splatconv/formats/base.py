"""What every format module shares: the one contract it fills (:class:`Format`) and the report a write returns.

Each format module ends with ``FORMAT = Format(...)``: its name and suffixes,
what it can do and how it stores the scene, and the functions that do it.
:mod:`splatconv.formats` registers these declarations and callers read them
(``format_for(path).holds_empty``); nothing outside ``formats/`` names a format.
The fields are stated here once; the architecture test reads them from here.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from ..errors import UnsupportedError
from ..model import MOTION, OMEGA
from ..viewer import TIME_RANGE, temporal_opacity
from ..wording import plural


@dataclass
class WriteReport:
    """What a write did, for the user.

    Attributes
    ----------
    count : int
        Splats written.
    notes : list of str
        Every lossy step, as sentences.
    texheight : int
        Texture rows (texture formats; 0 otherwise).
    half : dict
        Attribute -> :class:`splatconv.packing.HalfCounts` (half-float formats).
    clamped, nan_bytes : dict
        ``"color"``/``"alpha"`` -> values clamped to a byte / NaN written as 0.
    """

    count: int = 0
    notes: list = field(default_factory=list)
    texheight: int = 0
    half: dict = field(default_factory=dict)
    clamped: dict = field(default_factory=dict)
    nan_bytes: dict = field(default_factory=dict)

    def byte_notes(self) -> list:
        """Notes for the values clamped to a byte and the NaNs written as 0."""
        notes = [f"{key}: {plural(count, 'value')} outside [0, 1] clamped" for key, count in self.clamped.items() if count]
        return notes + [f"{key}: {plural(count, 'NaN value')} written as 0"
                        for key, count in self.nan_bytes.items() if count]



@dataclass
class Scan:
    """A scene read a piece at a time (what ``info`` reads): a :class:`~splatconv.model.Scene` whose
    columns come in pieces, so that reading it holds one piece, never the scene.

    Attributes
    ----------
    pieces : iterator of dict
        Consecutive rows of the scene, first to last: each a dict of ``(M,) float32`` columns, one per
        name in :data:`splatconv.model.COLUMNS`. Exhaust it inside the block that opened the file.
    cameras, variant, meta, notes
        As a :class:`~splatconv.model.Scene`'s; filled in as ``pieces`` is read, whole once it is exhausted.
    """

    pieces: Iterator = field(default_factory=lambda: iter(()))
    cameras: list | None = None
    variant: str = ""
    meta: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)


@dataclass(frozen=True, kw_only=True)
class Texture:
    """How a format that stores the viewer's texture itself packs and unpacks it.

    Attributes
    ----------
    encode : callable
        ``encode(scene, *, compat=None, sort=None) -> (records, WriteReport)``: the
        ``(N, 16) uint32`` records a write would store, in texture order.
    pieces : callable
        ``pieces(scene, put, *, compat=None, sort=None) -> WriteReport``: the same records
        a block at a time, ``put(block)`` with each in order (padding left out), never
        held whole.
    decode : callable
        ``decode(records) -> (columns, notes)``: the model's columns back from records.
    header : callable
        ``header(count, cameras) -> bytes``: what a file of ``count`` records holds before them.
    read : callable
        ``read(path) -> (padded, scene)``: a file's texture as the viewer holds it
        (``(rows * 1024, 16) uint32``, zero padded) and the scene decoded from it, in one read.
    """

    encode: Callable
    pieces: Callable
    decode: Callable
    header: Callable
    read: Callable


@dataclass(frozen=True, kw_only=True)
class Format:
    """One format's declaration: what it is, what it can do, and the functions that do it.

    Every format module fills one (``FORMAT``) and :mod:`splatconv.formats`
    registers it; callers ask it, never a module. Fields without a default are
    questions every format answers; the rest default to "no".

    Attributes
    ----------
    name : str
        What ``info`` and ``stats`` call the format.
    suffixes : tuple of str
        Lower-case file suffixes it claims (``.zst`` after one means the same, compressed).
    default_sort : {"importance", "none"}
        The record order a write uses when none is asked for.
    holds_empty : bool
        Whether a file can hold zero splats (an empty scene is refused otherwise).
    dynamic : bool
        Whether it holds motion and a temporal basis (False: static, a baked moment).
    read : callable or None
        ``read(path, **options) -> Scene``; None for a format that cannot be read.
    scan : callable or None
        ``scan(path, **options) -> Scan``: what ``read`` gives, a piece at a time (:class:`Scan`),
        holding a piece (a block or some thousands of rows), never the whole scene.
    splat_count, most_splats : callable or None
        Given exactly when ``read`` is, as ``scan`` is: ``splat_count(path) -> int or None`` (the
        splats ``read`` would give, from the header or the file size without reading
        them; None when only reading tells) and ``most_splats(path) -> int`` (at most
        that many, always known: it bounds the memory a read takes before it starts).
    write : callable or None
        ``write(scene, stream, *, compat=None, sort=None, progress=..., name=None, **options)
        -> WriteReport``; None for a format that cannot be written.
    info_fields : callable
        ``info_fields(meta) -> dict``: what ``info`` shows of a scene read from it
        (its ``meta``) besides the common facts.
    storage : callable
        ``storage(scene) -> dict``: how it stores each attribute group of ``scene``
        (a :data:`splatconv.compare.STORAGE_KINDS` name for each of
        :data:`splatconv.model.GROUPS`), which ``verify`` and ``stats`` judge errors by.
    compat_modes : tuple of str
        Byte-identical modes its writer offers (``compat=``).
    layouts : tuple of str
        Record layouts its writer offers (``layout=``).
    qualities : tuple of str
        Quality settings its writer offers (``quality=``), the default first.
    precisions : tuple of int
        Steps of precision its writer offers beside each quality (``precision=``),
        coarsest first: 0 is the quality as named, each two steps up about halve every
        quantizer's step. ``convert`` (its proof, ``--min-psnr``, ``--max-bytes``) walks them.
    tunings : tuple of str
        Quantizers its writer can coarsen a notch each beyond a precision step
        (``tune=``, a name once a notch), a file's header saying how: ``convert``'s proof
        tunes a setting to a scene with them where the scene has precision to spare.
    floors : dict
        Quality setting -> the worst-frame PSNR (dB) ``convert`` proves a file of that
        setting reaches unless told another floor (``--min-psnr``) or none.
    weighs : bool
        Its writer takes ``weights=``, what each splat adds to the frames a user
        sees (:func:`splatconv.ops.prune.contributions`), and spends its bits by
        them: ``convert``'s proof computes them once, from the views it proves.
    declared_size : callable or None
        ``declared_size(head) -> int or None``: the file size the header at the start
        of ``head`` (bytes) declares; bounds the decompression of a ``.zst`` file.
    texture : Texture or None
        Given when a file stores the viewer's texture itself: drawn, played and
        measured as stored. Exactly one writable format does (:func:`splatconv.formats.texture_format`).
    check_playable : callable or None
        Given when the player page plays this format's files as they are:
        ``check_playable(path)`` raises :class:`~splatconv.errors.FormatError` for a file
        the page could not play. Any other format is given to the page as the
        texture format's bytes, converted.
    converted_texture : callable or None
        ``converted_texture(path) -> (rows * 1024, 16) uint32``: the texture a conversion of
        the file to the texture format holds (zero padded), decoded without the scene: given
        by a format whose blocks decode to the texture's records (what a proof draws).
    prepare : callable or None
        ``prepare(scene, kinds=None) -> object``: what writes of ``scene`` at each of its
        :attr:`precisions` share, computed once and given to each as ``prepared=`` (a proof writes
        several); ``kinds``: the scene's :func:`~splatconv.viewer.undrawable_kinds`, where known.
    expands : bool
        A file is compressed inside: a small one can declare a scene many times
        its size (``most_splats``), so a read is held to the decompression ceiling
        (``--max-decompressed``) as a ``.zst`` file's is.
    holds_sh : bool
        A file can hold a scene's SH bands of degrees 1 to 3 (:data:`splatconv.model.SH_REST`); a
        write to any other format drops them and its report says so.
    drawable_only : bool
        A write leaves out the splats the viewer can never draw
        (:func:`splatconv.viewer.undrawable`) by itself, and its report says how many.
    companions : callable or None
        ``companions(path) -> tuple of str``: the files a write of ``path`` writes beside it (a
        ``.gltf``'s ``.bin``), checked as outputs and put in place with it, all or nothing; the
        writer gets their streams as ``companions=``, in that order. Such a file is never
        zstd-compressed (its companions would not be).
    """

    name: str
    suffixes: tuple
    default_sort: str
    holds_empty: bool
    dynamic: bool
    read: Callable | None
    write: Callable | None
    info_fields: Callable
    storage: Callable
    scan: Callable | None = None
    splat_count: Callable | None = None
    most_splats: Callable | None = None
    compat_modes: tuple = ()
    layouts: tuple = ()
    qualities: tuple = ()
    precisions: tuple[int, ...] = ()
    tunings: tuple[str, ...] = ()
    floors: dict = field(default_factory=dict, hash=False, compare=False)
    weighs: bool = False
    declared_size: Callable | None = None
    texture: Texture | None = None
    check_playable: Callable | None = None
    converted_texture: Callable | None = None
    prepare: Callable | None = None
    expands: bool = False
    drawable_only: bool = False
    holds_sh: bool = False
    companions: Callable | None = None

    def __post_init__(self):
        readers = (self.read, self.scan, self.splat_count, self.most_splats)
        if any(f is None for f in readers) != all(f is None for f in readers):
            raise TypeError(f"format {self.name}: read, scan, splat_count and most_splats come together")
        if self.read is None and self.write is None:
            raise TypeError(f"format {self.name}: neither read nor write")
        if (self.texture is not None or self.check_playable is not None or self.converted_texture is not None
                or self.expands) and self.read is None:
            raise TypeError(f"format {self.name}: a texture, a playable or an expanding file must be readable")
        if not self.suffixes or any(s != s.lower() or not s.startswith(".") for s in self.suffixes):
            raise TypeError(f"format {self.name}: suffixes must be lower-case and start with '.'")

    @property
    def can_read(self) -> bool:
        return self.read is not None

    @property
    def can_write(self) -> bool:
        return self.write is not None

    @property
    def stores_texture(self) -> bool:
        """Whether a file holds the viewer's texture itself (:attr:`texture`)."""
        return self.texture is not None

#: Smallest temporal opacity over the viewer's clip at which a static format
#: may drop a splat's temporal basis: the alpha byte moves by at most half a
#: step (sigmoid(opacity) * 255 * (1 - this) <= 0.5), so the viewer shows the
#: same picture at every time.
STATIC_MIN_TEMPORAL = 1.0 - 0.5 / 255.0


def fixed_storage(table: dict) -> Callable:
    """A :attr:`Format.storage` for a format that stores every scene alike: ``table``."""
    return lambda _scene: table


def meta_fields(*keys: str) -> Callable:
    """A :attr:`Format.info_fields` that shows these keys of a scene's ``meta`` (None where absent)."""
    return lambda meta: {key: meta.get(key) for key in keys}


def time_varying(columns: dict) -> np.ndarray:
    """Which splats the viewer shows differently at different times in [0, 1]: ``(N,) bool``.

    A splat is time-varying when any motion or omega coefficient is non-zero
    (NaN included), or when its temporal opacity falls below
    :data:`STATIC_MIN_TEMPORAL` somewhere in [0, 1] (also when it is NaN, or
    hidden by the viewer's cut). The temporal opacity peaks at the splat's
    centre, so its least value over [0, 1] is at one of the ends.
    """
    n = len(columns["x"])
    moving = np.zeros(n, dtype=bool)
    for name in MOTION + OMEGA:
        moving |= _constant_or_whole(columns[name]) != 0  # NaN != 0 too
    # A static scene's temporal basis is one value for every splat (model.static_columns): tested once.
    basis = {name: _constant_or_whole(columns[name]) for name in ("trbf_center", "trbf_scale")}
    if len(basis["trbf_center"]) != len(basis["trbf_scale"]):
        basis = {name: np.broadcast_to(np.asarray(columns[name]), (n,)) for name in basis}
    for t in TIME_RANGE:
        moving |= ~(temporal_opacity(basis, t, cut=False) >= STATIC_MIN_TEMPORAL)
    return moving


def _constant_or_whole(column) -> np.ndarray:
    """``column``'s first value alone when it holds one value for every row (a broadcast constant, stride
    0), else the whole column."""
    column = np.asarray(column)
    return column[:1] if column.ndim == 1 and len(column) and column.strides[0] == 0 else column


def refuse_nonfinite_positions(bad: int, holds: str) -> None:
    """Raise :class:`UnsupportedError` when ``bad`` splats have a NaN or infinite position, which a format
    that ``holds`` its positions so (bounded, fixed point) cannot store; the error says how to drop them."""
    if bad:
        raise UnsupportedError(f"{plural(bad, 'splat')} with a NaN or infinite position: {holds} "
                               "(drop them with `convert --drop-nonfinite`)")


def refuse_time_varying(columns: dict, what: str) -> None:
    """Raise :class:`UnsupportedError` when a static format ``what`` cannot hold the scene's motion or fading.

    Writing such a scene as static would show, at every time, splats that
    move, turn or fade in the clip, each frozen at its own rest time: a picture
    the scene never shows. Baking a moment is the way to a static file.
    """
    varying = int(np.count_nonzero(time_varying(columns)))
    if varying:
        n = len(columns["x"])
        raise UnsupportedError(
            f"{varying:,} of {plural(n, 'splat')} move, turn or fade over time and {what} is static; bake one moment "
            "with `splatconv bake INPUT OUTPUT --time T`")
