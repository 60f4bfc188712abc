"""zstd transport: the size a web server sends with ``Content-Encoding: zstd``.

Compression and decompression stream through fixed-size buffers, so a large file
never sits in memory twice.
"""

from __future__ import annotations

import contextlib
import os
import tempfile

import zstandard

from .errors import FormatError, SplatconvError

#: Default zstd level for reports and ``.zst`` output: 19, zstd's highest level
#: before the "ultra" ones, worth it for files served many times.
DEFAULT_LEVEL = 19
SUFFIX = ".zst"


class _Counter:
    """A write-only sink that only counts bytes."""

    def __init__(self):
        self.count = 0

    def write(self, data) -> int:
        n = memoryview(data).nbytes  # len() of a 2-D array's memoryview counts rows
        self.count += n
        return n


class _Tee:
    """A write-only stream that counts what passes and hands it on."""

    def __init__(self, counter: _Counter, out):
        self.counter = counter
        self.out = out

    def write(self, data) -> int:
        self.counter.write(data)
        return self.out.write(data)


def compressor(level: int = DEFAULT_LEVEL):
    """The ``zstandard.ZstdCompressor`` every ``.zst`` output and size goes through."""

    # threads=-1: one worker per core; the frame is the same format either way.
    return zstandard.ZstdCompressor(level=level, threads=-1, write_content_size=True)


def compressed_size(path: str | os.PathLike, level: int = DEFAULT_LEVEL) -> int:
    """Bytes of ``path`` compressed with zstd at ``level``, streamed, nothing written."""
    sink = _Counter()
    with open(path, "rb") as f:
        compressor(level).copy_stream(f, sink, size=os.fstat(f.fileno()).st_size)
    return sink.count


def written_sizes(write, level: int = DEFAULT_LEVEL) -> tuple[int, int]:
    """Sizes of what ``write(stream)`` writes, plain and zstd-compressed at ``level``.

    The bytes are compressed as they are written and then dropped: nothing is
    kept but the compressor's own window and in-flight jobs.

    Parameters
    ----------
    write : callable
        Called once with a binary write-only stream.

    Returns
    -------
    plain, compressed : int
        Bytes.
    """
    plain, sink = _Counter(), _Counter()
    with compressor(level).stream_writer(sink, closefd=False) as z:
        write(_Tee(plain, z))
    return plain.count, sink.count


def is_compressed(path) -> bool:
    """True for a ``.zst`` path (``scene.splatv.zst``, ``scene.ply.zst``)."""
    return os.fspath(path).lower().endswith(SUFFIX)


def inner_name(path) -> str:
    """The path without its ``.zst`` suffix (which names the format inside)."""
    path = os.fspath(path)
    return path[: -len(SUFFIX)] if is_compressed(path) else path


@contextlib.contextmanager
def plain_input(path):
    """Yield a path to the uncompressed bytes of ``path``.

    A ``.zst`` file is stream-decompressed into a temporary file (removed on exit;
    memory maps of it stay valid on POSIX), so a large scene never sits in memory
    twice. Errors raised inside name ``path``, not the temporary file.
    """

    path = os.fspath(path)
    if not is_compressed(path):
        yield path
        return

    suffix = os.path.splitext(inner_name(path))[1]
    fd, tmp = tempfile.mkstemp(prefix="splatconv-", suffix=suffix)
    try:
        with os.fdopen(fd, "wb") as out:
            try:
                with open(path, "rb") as f:
                    zstandard.ZstdDecompressor().copy_stream(f, out)
            except FileNotFoundError:
                raise FormatError("cannot open: No such file or directory", path) from None
            except zstandard.ZstdError as e:
                raise FormatError(f"not a valid zstd stream ({e})", path) from None
        try:
            yield tmp
        except SplatconvError as e:
            if e.path == tmp:
                e.path = path
            raise
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


@contextlib.contextmanager
def output_stream(stream, path, level: int = DEFAULT_LEVEL):
    """Wrap a binary output stream in a zstd compressor when ``path`` ends in ``.zst``."""
    if not is_compressed(path):
        yield stream
        return
    with compressor(level).stream_writer(stream, closefd=False) as z:
        yield z
