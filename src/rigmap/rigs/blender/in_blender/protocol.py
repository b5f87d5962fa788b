"""The wire format between rigmap and a Blender worker: length-prefixed frames.

A frame is ``MAGIC | header length (u32) | body length (u64) | header | body``.
The header is UTF-8 JSON (an operation and its plain arguments); the body holds
the numpy arrays the header lists as ``[name, dtype, shape]``, raw little-endian
bytes one after another. Nothing is pickled: the two ends run different numpy
versions (Blender's bpy pins numpy<2), and raw bytes plus a shape mean the same
to both.

This module is imported on both sides, so it needs only the standard library
and numpy, and imports nothing from rigmap.
"""

from __future__ import annotations

import json
import struct

import numpy as np

MAGIC = b"RGMP"
PROTOCOL_VERSION = 1
_PREFIX = struct.Struct("<4sIQ")
PREFIX_SIZE = _PREFIX.size
MAX_HEADER_BYTES = 64 * 1024 * 1024
MAX_BODY_BYTES = 16 * 1024 * 1024 * 1024
# The only array types that cross the boundary; anything else is converted first.
WIRE_DTYPES = {"f8": np.dtype("<f8"), "i8": np.dtype("<i8")}


class ProtocolError(RuntimeError):
    """Bytes on the channel that are not a well-formed frame."""


def encode_frame(header: dict, arrays: dict | None = None) -> bytes:
    """One frame holding ``header`` (JSON-able) and ``arrays`` (name -> numpy array)."""
    specs, chunks = [], []
    for name, array in (arrays or {}).items():
        array = np.asarray(array)
        code = "i8" if array.dtype.kind in "iub" else "f8"
        data = np.ascontiguousarray(array, dtype=WIRE_DTYPES[code])
        specs.append([name, code, list(data.shape)])
        chunks.append(data.tobytes())
    head = json.dumps({**header, "arrays": specs}, separators=(",", ":")).encode("utf-8")
    body = b"".join(chunks)
    return _PREFIX.pack(MAGIC, len(head), len(body)) + head + body


def parse_prefix(prefix: bytes) -> tuple[int, int]:
    """Header and body lengths from the fixed-size start of a frame."""
    if len(prefix) != PREFIX_SIZE:
        raise ProtocolError(f"frame prefix must be {PREFIX_SIZE} bytes, got {len(prefix)}")
    magic, head_len, body_len = _PREFIX.unpack(prefix)
    if magic != MAGIC:
        raise ProtocolError(f"frame does not start with {MAGIC!r}: got {prefix[:16]!r}")
    if head_len > MAX_HEADER_BYTES or body_len > MAX_BODY_BYTES:
        raise ProtocolError(f"frame too large: header {head_len} bytes, body {body_len} bytes")
    return head_len, body_len


def decode_payload(head: bytes, body: bytes) -> tuple[dict, dict]:
    """The header dict and the arrays (writable copies) of one frame."""
    try:
        header = json.loads(head.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ProtocolError(f"frame header is not UTF-8 JSON: {error}") from None
    arrays, offset = {}, 0
    for name, code, shape in header.pop("arrays", []):
        if code not in WIRE_DTYPES:
            raise ProtocolError(f"array {name!r}: dtype {code!r} not in {sorted(WIRE_DTYPES)}")
        dtype = WIRE_DTYPES[code]
        count = int(np.prod(shape, dtype=np.int64))
        end = offset + count * dtype.itemsize
        if end > len(body):
            raise ProtocolError(
                f"array {name!r} of shape {shape} needs bytes {offset}..{end}, body has {len(body)}"
            )
        arrays[name] = np.frombuffer(body, dtype, count, offset).reshape(shape).copy()
        offset = end
    if offset != len(body):
        raise ProtocolError(f"frame body has {len(body) - offset} bytes no array claims")
    return header, arrays


def read_frame(read_exact) -> tuple[dict, dict] | None:
    """Read one frame with ``read_exact(n) -> bytes``; ``None`` on a clean end of stream.

    ``read_exact`` returns fewer than ``n`` bytes only at end of stream.
    """
    prefix = read_exact(PREFIX_SIZE)
    if not prefix:
        return None
    if len(prefix) < PREFIX_SIZE:
        raise ProtocolError(f"stream ended inside a frame prefix ({len(prefix)} bytes)")
    head_len, body_len = parse_prefix(prefix)
    head = read_exact(head_len)
    body = read_exact(body_len)
    if len(head) < head_len or len(body) < body_len:
        raise ProtocolError(
            f"stream ended inside a frame: header {len(head)}/{head_len} bytes, "
            f"body {len(body)}/{body_len} bytes"
        )
    return decode_payload(head, body)
