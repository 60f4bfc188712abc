"""zstd: ``.zst`` files read and written as a stream, and the transport size (what a web server
sends with ``Content-Encoding: zstd``).

Compression (:func:`output_stream`, :func:`compressed_bytes`) and decompression
(:func:`plain_input`, with the ceiling of ``--max-decompressed``) stream through
fixed-size buffers, so a large file never sits in memory twice.
"""

from __future__ import annotations

import contextlib
import os

import zstandard

from .errors import FormatError, OutputError, SplatconvError, UsageError
from .files.stale import locked_temporary
from .files.inputs import open_input
from .progress import SILENT

#: Default zstd level for reports and ``.zst`` output: 3, zstd's own default.
#: Measured on 1,000,000-splat scenes (``bench/bench_zstd_levels.py``, table in
#: specs/zstd.md): a .splatv at level 3 is about 8% larger than at level 19 but is
#: compressed some 90 times faster (level 19 took minutes, and ~300 MB); levels
#: 6 and 9 save 4-6% more for two and four times the time. ``--zstd-level``
#: chooses another.
DEFAULT_LEVEL = 3
SUFFIX = ".zst"


class _Counter:
    """A write-only sink that only counts bytes."""

    def __init__(self):
        self.count = 0

    def write(self, data) -> int:
        n = memoryview(data).nbytes  # len() of a 2-D array's memoryview counts rows
        self.count += n
        return n


class _Reporting:
    """Where a compressor writes: hands its output on and tells ``advance`` the input bytes compressed.

    zstd's worker threads compress in jobs of megabytes; at high levels the
    frame's last jobs are finished only when it is closed, seconds after the
    last write. Each piece of compressed output arrives here, so the input
    bytes consumed so far (``frame_progression``) show how far that is.
    """

    def __init__(self, out, cctx):
        self.out = out
        self.cctx = cctx
        self.advance = None
        self.done = 0

    def write(self, data) -> int:
        self.report()
        return self.out.write(data)

    def flush(self) -> None:
        flush = getattr(self.out, "flush", None)
        if flush is not None:
            flush()

    def report(self) -> None:
        if self.advance is not None:
            consumed = self.cctx.frame_progression()[1]
            if consumed > self.done:
                self.advance(consumed - self.done)
                self.done = consumed


def compressor(level: int = DEFAULT_LEVEL, size_hint: int | None = None):
    """The ``zstandard.ZstdCompressor`` every ``.zst`` output and size goes through.

    ``size_hint``: about how many bytes it will be given, when that is not known
    exactly (a size given to its stream writer is used exactly). The window and
    match tables are then sized for that many bytes instead of the level's
    largest: level 22 takes 128 MiB of window and some 640 MiB of context a
    worker when the size is unknown, about 130 MiB in all for a 6 MB file. The
    output decompresses to the same bytes whatever the hint; a hint below the
    true size only shortens the distance matches are looked for.
    """
    # threads=-1: one worker per core; the frame is the same format either way.
    if size_hint is None:
        return zstandard.ZstdCompressor(level=level, threads=-1, write_content_size=True)
    params = zstandard.ZstdCompressionParameters.from_level(level, source_size=max(1, size_hint), threads=-1,
                                                            write_content_size=1)
    return zstandard.ZstdCompressor(compression_params=params)


def _failure(e: Exception, level: int, path=None) -> SplatconvError:
    """A compressor's failure as one line: zstd's own reason, and what to do when it is memory."""
    reason = "not enough memory" if isinstance(e, MemoryError) else str(e).split("error: ", 1)[-1]
    memory = isinstance(e, MemoryError) or "memory" in reason.lower() or "allocation" in reason.lower()
    hint = "; a lower --zstd-level needs less" if memory else ""
    return OutputError(f"zstd level {level} could not compress ({reason}){hint}", path)


def compressed_bytes(pieces, size: int, level: int = DEFAULT_LEVEL, *, progress=SILENT,
                     label: str = "compressing") -> int:
    """Bytes of the ``size`` bytes ``pieces`` yields (buffers), zstd-compressed at ``level`` as one frame.

    The frame declares its content size, as ``zstd FILE`` writes it; nothing is
    kept. ``progress`` is told the input bytes compressed, in a stage named ``label``.
    """
    cctx = compressor(level)
    sink = _Reporting(_Counter(), cctx)
    with progress.stage(label, size, "byte") as advance:
        sink.advance = advance
        try:
            with cctx.stream_writer(sink, size=size, closefd=False) as z:
                for piece in pieces:
                    z.write(piece)
        except (zstandard.ZstdError, MemoryError) as e:
            raise _failure(e, level) from None
        sink.report()
    return sink.out.count


def is_compressed(path) -> bool:
    """True for a ``.zst`` path (``scene.splatv.zst``, ``scene.ply.zst``)."""
    return os.fspath(path).lower().endswith(SUFFIX)


def inner_name(path) -> str:
    """The path without its ``.zst`` suffix (which names the format inside)."""
    path = os.fspath(path)
    return path[: -len(SUFFIX)] if is_compressed(path) else path


#: Default ceiling on the bytes a ``.zst`` input may decompress to, and on the
#: memory the scene read from it may take at the peak of the command reading it
#: (2 GiB: 11.1 million splats for ``convert``, 192 bytes a splat, see
#: :func:`splatconv.io.check_memory`). A few hundred
#: kilobytes of zstd can expand to gigabytes; this bounds the temporary file and
#: what reading it costs. Raised with ``--max-decompressed`` or the environment
#: variable :data:`MAX_DECOMPRESSED_ENV`.
DEFAULT_MAX_DECOMPRESSED = 2 << 30
MAX_DECOMPRESSED_ENV = "SPLATCONV_MAX_DECOMPRESSED"
#: Bytes past the end a format's header declares that are still decompressed,
#: so a reader sees (and reports) trailing bytes as it does in a plain file.
TRAILING_SLACK = 1 << 20
#: Bytes of decompressed data handed to a format's ``declared_size``.
HEAD_BYTES = 1 << 20
_READ_STEP = 1 << 20
_UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}
_max_decompressed: int | None = None


def parse_byte_size(text: str) -> int:
    """``"2G"``, ``"512M"``, ``"64k"``, ``"1000000"`` -> bytes (binary units, an optional ``B`` or ``iB``).

    Raises
    ------
    ValueError
    """
    t = str(text).strip().lower()
    for tail in ("ib", "b"):
        if t.endswith(tail) and len(t) > len(tail):
            t = t[: -len(tail)]
            break
    unit = t[-1:] if t[-1:] in _UNITS and t[-1:] else ""
    number = t[: len(t) - len(unit)].strip()
    if not number.isdigit() or len(number) > 20:
        raise ValueError(f"expected a byte count such as 4G, 512M or 1000000, got {text!r}")
    return int(number) * _UNITS[unit]


def set_max_decompressed(limit: int | None) -> None:
    """Set the ceiling on decompressed bytes for this process (None: back to the environment / default)."""
    global _max_decompressed
    if limit is not None and limit < 0:
        raise ValueError("the ceiling must be a non-negative byte count")
    _max_decompressed = limit


def max_decompressed() -> int:
    """The ceiling in force: :func:`set_max_decompressed`, else the environment variable, else the default.

    Raises
    ------
    UsageError
        When the environment variable is not a byte count.
    """
    if _max_decompressed is not None:
        return _max_decompressed
    env = os.environ.get(MAX_DECOMPRESSED_ENV)
    if env is None or not env.strip():
        return DEFAULT_MAX_DECOMPRESSED
    try:
        return parse_byte_size(env)
    except ValueError as e:
        raise UsageError(f"{MAX_DECOMPRESSED_ENV}: {e}") from None


def describe_bytes(n: int) -> str:
    """``n`` bytes in words: "2 GiB", "512 MiB", or "1,000,000 bytes" when not whole mebibytes."""
    return f"{n:,} bytes" if n < 1 << 20 or n % (1 << 20) else (
        f"{n >> 30} GiB" if n % (1 << 30) == 0 else f"{n >> 20} MiB")


@contextlib.contextmanager
def plain_input(path, declared_size=None, progress=SILENT):
    """Yield a path to the uncompressed bytes of ``path``.

    A ``.zst`` file is stream-decompressed into a temporary file (removed on
    exit, by Ctrl-C, SIGTERM and SIGHUP too; memory maps of it stay valid on
    POSIX), so a large scene never sits in memory twice. Decompression stops at
    :func:`max_decompressed` bytes, at the content size the first zstd frame
    declares, and, with ``declared_size``, at what the format's own header
    declares (plus :data:`TRAILING_SLACK`): past any of them it is an error and
    the temporary file is removed. Errors raised inside name ``path``, not the
    temporary file.

    Parameters
    ----------
    path : path
    declared_size : callable, optional
        ``declared_size(head) -> int or None``: the file size the format's header
        declares, from the first :data:`HEAD_BYTES` decompressed bytes (None:
        the header does not say, or is longer).
    progress : splatconv.progress.Progress
        Told the compressed bytes read, in a "decompressing NAME" stage.
    """

    path = os.fspath(path)
    if not is_compressed(path):
        yield path
        return

    ceiling = max_decompressed()
    suffix = os.path.splitext(inner_name(path))[1]
    with open_input(path) as f:
        frame = f.read(18)  # the longest zstd frame header
        f.seek(0)
        with contextlib.suppress(zstandard.ZstdError):
            content = zstandard.frame_content_size(frame)
            if content > ceiling:
                raise FormatError(f"its zstd frame declares {content:,} decompressed bytes, more than the "
                                  f"{describe_bytes(ceiling)} allowed (raise it with --max-decompressed or "
                                  f"{MAX_DECOMPRESSED_ENV})", path)
        with locked_temporary(suffix) as (fd, tmp):
            # Progress in compressed bytes read: the file's size is always known, the content's not always.
            with os.fdopen(fd, "wb") as out, \
                    progress.stage(f"decompressing {os.path.basename(path)}", os.fstat(f.fileno()).st_size,
                                   "byte") as advance:
                try:
                    _decompress(f, out, path, ceiling, declared_size, advance)
                except zstandard.ZstdError as e:
                    # "zstd decompress error: Unknown frame descriptor": the library's prefix says nothing
                    raise FormatError(f"not a valid zstd stream ({str(e).split('error: ', 1)[-1]})", path) from None
                except OSError as e:
                    # A full disk names no file; the temporary file's random name would say nothing either.
                    raise OutputError(f"cannot decompress into the temporary folder {os.path.dirname(tmp)}: "
                                      f"{e.strerror or e} (TMPDIR chooses another folder)", path) from None
            try:
                yield tmp
            except SplatconvError as e:
                if e.path == tmp:
                    e.path = path
                raise


def _decompress(f, out, path: str, ceiling: int, declared_size, advance) -> None:
    """Copy the decompressed bytes of ``f`` to ``out``, never more than the limits allow."""
    limit = ceiling
    declared = None
    head = b"" if declared_size is not None else None
    written = read = 0
    with zstandard.ZstdDecompressor().stream_reader(f, read_across_frames=True) as reader:
        while True:
            chunk = reader.read(min(_READ_STEP, limit + 1 - written))
            if not chunk:
                return
            if written + len(chunk) > limit:
                if declared is not None:
                    raise FormatError(f"decompresses to more than the {declared:,} bytes its header declares "
                                      f"(and {describe_bytes(TRAILING_SLACK)} of trailing data allowed)", path)
                raise FormatError(f"decompresses to more than the {describe_bytes(limit)} allowed (raise it with "
                                  f"--max-decompressed or {MAX_DECOMPRESSED_ENV})", path)
            out.write(chunk)
            written += len(chunk)
            advance(f.tell() - read)
            read = f.tell()
            if head is not None:
                head += chunk[: HEAD_BYTES - len(head)]
                if len(head) >= HEAD_BYTES:
                    declared = declared_size(head)
                    if declared is not None and declared + TRAILING_SLACK < limit:
                        limit = declared + TRAILING_SLACK
                    else:
                        declared = None
                    head = None


@contextlib.contextmanager
def output_stream(stream, path, level: int = DEFAULT_LEVEL, progress=SILENT, size_hint: int | None = None):
    """Wrap a binary output stream in a zstd compressor when ``path`` ends in ``.zst``.

    Finishing the frame, after the last write, compresses what the worker
    threads still hold (seconds at high levels): ``progress`` is told those
    bytes in a "compressing" stage. ``size_hint``: about the bytes that will be
    written (:func:`compressor`), so that a high level takes the memory the data
    needs, not the level's most.

    Raises
    ------
    OutputError
        Naming ``path``, when the compressor fails (at a high level, out of memory).
    """
    if not is_compressed(path):
        yield stream
        return
    try:
        cctx = compressor(level, size_hint)
    except (zstandard.ZstdError, MemoryError) as e:
        raise _failure(e, level, path) from None
    sink = _Reporting(stream, cctx)
    z = cctx.stream_writer(sink, closefd=False)
    # Not ``with``: on an error or a signal the frame is abandoned, not finished
    # (finishing compresses everything still buffered, seconds at high levels,
    # for a file that is about to be removed).
    yield _Pieces(z, level, path)
    ingested, consumed, _ = cctx.frame_progression()
    with progress.stage("compressing", ingested - consumed, "byte") as advance:
        sink.advance, sink.done = advance, consumed
        try:
            z.close()
        except (zstandard.ZstdError, MemoryError) as e:
            raise _failure(e, level, path) from None


class _Pieces:
    """Hands writes on in pieces of at most :data:`_WRITE_STEP` bytes.

    A signal handler (SIGTERM, Ctrl-C) runs only between two calls into C; one
    multi-megabyte write at zstd's highest levels takes seconds, a piece a fraction of one.
    A compressor's failure is an :class:`OutputError` naming the output.
    """

    def __init__(self, out, level: int, path):
        self.out = out
        self.level = level
        self.path = path

    def write(self, data) -> int:
        view = memoryview(data).cast("B")
        try:
            for start in range(0, len(view), _WRITE_STEP):
                self.out.write(view[start:start + _WRITE_STEP])
        except (zstandard.ZstdError, MemoryError) as e:
            raise _failure(e, self.level, self.path) from None
        return len(view)


_WRITE_STEP = 1 << 18
