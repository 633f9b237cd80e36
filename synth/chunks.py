"""The chunk files of a recording's ``clean_diff``: their layout, read and written directly.

A store on disk laid out as the pipeline writes it (chunks of one frame, CHUNK x CHUNK px,
bytes little-endian + zstd, no sharding) has its chunk files read, decoded and written here
(numcodecs' Zstd, the codec zarr's ZstdCodec calls), synchronously, without zarr's event-loop
thread; any other store goes through zarr (:mod:`synth.store`). A region read decodes only the
chunks it touches, and a render worker encodes only the chunks its tiles touch. The bytes are
the same as zarr's (tested).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from synth.config import SynthError

CHUNK = 128  # px: clean_diff chunk side (a chunk of int16 is 32 kB; 80 cover 1280 x 1024)

def _layout(group, arr):
    """(folder, chunk key function, little-endian dtype, chunk shape, frame shape, zstd level)
    of ``clean_diff`` when it is laid out as the pipeline writes it (a local directory, chunks
    of one frame, bytes little-endian + zstd without checksum, fill 0, no sharding); None
    otherwise."""
    import zarr
    from zarr.codecs import BytesCodec, ZstdCodec

    try:
        root = group.store.root if isinstance(group.store, zarr.storage.LocalStore) else None
        meta = arr.metadata
        codecs = tuple(meta.codecs)
        ok = (root is not None and arr.ndim == 3 and arr.chunks[0] == 1
              and len(codecs) == 2 and isinstance(codecs[0], BytesCodec)
              and str(getattr(codecs[0].endian, "value", codecs[0].endian)) == "little"
              and isinstance(codecs[1], ZstdCodec) and not codecs[1].checksum
              and not meta.storage_transformers
              and np.dtype(arr.dtype) in (np.int16, np.int32) and meta.fill_value == 0)
    except Exception:  # another zarr layout or version: let zarr read it
        return None
    if not ok:
        return None
    return (Path(root) / arr.path, meta.chunk_key_encoding.encode_chunk_key,
            np.dtype(arr.dtype).newbyteorder("<"), tuple(arr.chunks[1:]), tuple(arr.shape[1:]),
            codecs[1].level)


def chunk_files(group, arr):
    """A function (i, (y0, y1, x0, x1)) -> that region of frame i's ``clean_diff`` (int32),
    decoded from the chunk files it touches, or None when the store is not laid out as the
    pipeline writes it (then zarr reads)."""
    layout = _layout(group, arr)
    if layout is None:
        return None
    from numcodecs.zstd import decompress

    folder, encode, dtype, (ch, cw), _, _ = layout
    root = str(folder)
    # the chunk files' names as writer_layout's prefix and separator make them (zarr's own
    # encoder, a Python call, where they do not give its names)
    named = writer_layout(group, arr)
    if named is not None:
        prefix, sep = os.path.join(root, named[1]), named[2]

        def path(i, cy, cx):
            return f"{prefix}{i}{sep}{cy}{sep}{cx}"
    else:
        def path(i, cy, cx):
            return os.path.join(root, encode((i, cy, cx)))
    # one read of this many bytes holds a whole chunk file (zstd's bound on a chunk is its
    # size plus 0.4 %): no fstat for its size
    cap = 2 * ch * cw * dtype.itemsize + 4096

    def read(i: int, roi) -> np.ndarray:
        y0, y1, x0, x1 = roi
        out = np.zeros((y1 - y0, x1 - x0), dtype=np.int32)
        for cy in range(y0 // ch, (y1 - 1) // ch + 1):
            for cx in range(x0 // cw, (x1 - 1) // cw + 1):
                # os-level reads and numcodecs' zstd decompress (what Zstd.decode calls): a
                # third of pathlib's read_bytes + Zstd.decode's CPU for a 32 kB chunk
                try:
                    fd = os.open(path(i, cy, cx), os.O_RDONLY)
                except FileNotFoundError:  # a chunk never written: all fill value
                    continue
                except OSError as exc:
                    raise SynthError(f"{folder}: cannot read frame {i}'s chunk ({exc})") from None
                try:
                    data = os.read(fd, cap)
                    if len(data) == cap:  # larger than any chunk (corrupt): read it all
                        parts = [data]
                        while parts[-1]:
                            parts.append(os.read(fd, cap))
                        data = b"".join(parts)
                except OSError as exc:
                    raise SynthError(f"{folder}: cannot read frame {i}'s chunk ({exc})") from None
                finally:
                    os.close(fd)
                try:
                    chunk = np.frombuffer(decompress(data), dtype=dtype).reshape(ch, cw)
                except Exception as exc:
                    raise SynthError(f"{folder}: frame {i}'s chunk is corrupt ({exc})") from None
                ya, yb = max(y0, cy * ch), min(y1, (cy + 1) * ch)
                xa, xb = max(x0, cx * cw), min(x1, (cx + 1) * cw)
                out[ya - y0:yb - y0, xa - x0:xb - x0] = chunk[ya - cy * ch:yb - cy * ch,
                                                              xa - cx * cw:xb - cx * cw]
        return out

    return read


def writer_layout(group, arr):
    """Where and how :func:`chunk_writer` writes ``clean_diff``'s chunks, as plain values (a
    render process writes with them without importing zarr: :func:`chunk_writer_at`).

    Parameters
    ----------
    group : zarr.Group
        The recording's group (a local directory store).
    arr : zarr.Array
        Its ``clean_diff`` array, as :func:`synth.pipeline.render` creates it.

    Returns
    -------
    tuple or None
        (folder, chunk key prefix, key separator, dtype string, chunk shape, frame shape, zstd
        level); None when the array is not laid out as the pipeline writes it or its chunk
        keys are not ``prefix + separator.join(indices)``.
    """
    layout = _layout(group, arr)
    if layout is None:
        return None
    folder, encode, dtype, chunk, frame, level = layout
    try:
        enc = arr.metadata.chunk_key_encoding
        sep = str(getattr(enc.separator, "value", enc.separator))
        prefix = {"v2": "", "default": "c" + sep}[enc.name]
    except (AttributeError, KeyError):
        return None
    probe = (12, 3, 4)
    if encode(probe) != prefix + sep.join(map(str, probe)):
        return None
    return (str(folder), prefix, sep, dtype.str, chunk, frame, level)


def chunk_writer(group, arr):
    """A function (i, patches) writing frame i of ``clean_diff`` (a pipeline-made array) from
    ``patches`` [((x0, y0, w, h), values), ...] (the frame is zero elsewhere): only the chunks
    the patches touch are encoded and written, and those left all zero are not (as zarr's
    ``write_empty_chunks=False``). The files are those zarr writes (tested).

    Parameters
    ----------
    group : zarr.Group
        The recording's group (a local directory store).
    arr : zarr.Array
        Its ``clean_diff`` array, as :func:`synth.pipeline.render` creates it.

    Returns
    -------
    callable
        ``write(i, patches)``.

    Raises
    ------
    SynthError
        When the array is not laid out as the pipeline writes it.
    """
    return chunk_writer_at(writer_layout(group, arr))


def chunk_writer_at(layout):
    """:func:`chunk_writer` from its :func:`writer_layout` (no zarr needed).

    Parameters
    ----------
    layout : tuple or None
        :func:`writer_layout`'s values.

    Returns
    -------
    callable
        ``write(i, patches)``.

    Raises
    ------
    SynthError
        When ``layout`` is None (the array is not laid out as the pipeline writes it).
    """
    if layout is None:
        raise SynthError("clean_diff is not laid out as synth's pipeline writes it")
    # numcodecs' Zstd(level).encode(chunk) is compress(chunk, level, False) (no checksum):
    # the same bytes, without the codec's buffer checks and a copy of the chunk; the files are
    # created, written and closed as pathlib's write_bytes does (open(path, "wb"): O_WRONLY |
    # O_CREAT | O_TRUNC | O_CLOEXEC, mode 0o666 less the umask), without its path objects
    from numcodecs.zstd import compress

    root, prefix, sep, dtype, (ch, cw), (H, W), level = layout
    folder = str(root)
    dtype = np.dtype(dtype)
    flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_CLOEXEC", 0)

    def write(i: int, patches) -> None:
        chunks: dict = {}
        for (x0, y0, w, h), values in patches:
            x1, y1 = min(x0 + w, W), min(y0 + h, H)
            for cy in range(y0 // ch, (y1 - 1) // ch + 1):
                for cx in range(x0 // cw, (x1 - 1) // cw + 1):
                    chunk = chunks.get((cy, cx))
                    if chunk is None:
                        chunk = chunks[(cy, cx)] = np.zeros((ch, cw), dtype=dtype)
                    ya, yb = max(y0, cy * ch), min(y1, (cy + 1) * ch)
                    xa, xb = max(x0, cx * cw), min(x1, (cx + 1) * cw)
                    chunk[ya - cy * ch:yb - cy * ch, xa - cx * cw:xb - cx * cw] = \
                        values[ya - y0:yb - y0, xa - x0:xb - x0]
        for (cy, cx), chunk in chunks.items():
            if chunk.any():
                data = memoryview(compress(chunk, level, False))
                fd = os.open(os.path.join(folder, f"{prefix}{i}{sep}{cy}{sep}{cx}"), flags,
                             0o666)
                try:
                    while data:
                        data = data[os.write(fd, data):]
                finally:
                    os.close(fd)

    return write
