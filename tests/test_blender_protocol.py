"""The worker wire format: frames round-trip arrays exactly and reject broken bytes."""

from __future__ import annotations

import io

import numpy as np
import pytest

from rigmap.rigs.blender.in_blender import protocol


def roundtrip(header, arrays=None):
    return protocol.read_frame(io.BytesIO(protocol.encode_frame(header, arrays)).read)


def test_arrays_and_header_come_back_exactly():
    rng = np.random.default_rng(3)
    arrays = {
        "controls": rng.normal(size=(5, 7)),
        "positions": rng.normal(size=(2, 3, 3)) * 1e6,
        "index": np.array([3, -1, 2**40]),
        "empty": np.zeros((0, 4)),
    }
    header, out = roundtrip({"op": "evaluate", "args": {"name": "ü", "n": 3}}, arrays)
    assert header == {"op": "evaluate", "args": {"name": "ü", "n": 3}}
    assert set(out) == set(arrays)
    for name, array in arrays.items():
        assert out[name].shape == array.shape
        assert np.array_equal(out[name], array)
    assert out["index"].dtype == np.int64 and out["controls"].dtype == np.float64
    out["controls"][0, 0] = 1.0  # decoded arrays are writable copies


def test_float32_is_widened_to_float64_without_change():
    values = np.array([[0.1, -2.5]], dtype=np.float32)
    _, out = roundtrip({"op": "x"}, {"v": values})
    assert out["v"].dtype == np.float64
    assert np.array_equal(out["v"], values.astype(np.float64))


def test_frames_follow_each_other_and_end_cleanly():
    stream = io.BytesIO(
        protocol.encode_frame({"op": "a"}, {"x": np.arange(3.0)})
        + protocol.encode_frame({"op": "b"})
    )
    assert protocol.read_frame(stream.read)[0] == {"op": "a"}
    assert protocol.read_frame(stream.read)[0] == {"op": "b"}
    assert protocol.read_frame(stream.read) is None


def test_truncated_frame_is_an_error_not_a_short_array():
    frame = protocol.encode_frame({"op": "a"}, {"x": np.arange(10.0)})
    with pytest.raises(protocol.ProtocolError, match="stream ended inside a frame"):
        protocol.read_frame(io.BytesIO(frame[:-8]).read)
    with pytest.raises(protocol.ProtocolError, match="prefix"):
        protocol.read_frame(io.BytesIO(frame[:5]).read)


def test_wrong_magic_is_reported_with_the_bytes():
    frame = protocol.encode_frame({"op": "a"})
    with pytest.raises(protocol.ProtocolError, match="Read blend"):
        protocol.read_frame(io.BytesIO(b"Read blend: x" + frame).read)


def test_header_claiming_more_array_bytes_than_the_body_has():
    head = b'{"arrays":[["x","f8",[4]]]}'
    body = np.zeros(3).tobytes()
    with pytest.raises(protocol.ProtocolError, match="array 'x'"):
        protocol.decode_payload(head, body)
    with pytest.raises(protocol.ProtocolError, match="no array claims"):
        protocol.decode_payload(b'{"arrays":[]}', body)
    with pytest.raises(protocol.ProtocolError, match="dtype"):
        protocol.decode_payload(b'{"arrays":[["x","f4",[1]]]}', b"\0\0\0\0")
