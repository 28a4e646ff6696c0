"""Tiny ONNX models written as protobuf bytes by hand, for the tests of models of the wrong
layout (the ``onnx`` package is not a dependency of fastdet; ``onnx.helper`` would make the
same bytes). Only the fields an Identity graph needs:

ModelProto: ir_version = 1, graph = 7, opset_import = 8; OperatorSetIdProto: version = 2;
GraphProto: node = 1, name = 2, input = 11, output = 12; NodeProto: input = 1, output = 2,
op_type = 4; ValueInfoProto: name = 1, type = 2; TypeProto: tensor_type = 1;
TypeProto.Tensor: elem_type = 1, shape = 2; TensorShapeProto: dim = 1;
Dimension: dim_value = 1, dim_param = 2. Element types: 1 float32, 7 int64.
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

FLOAT, INT64 = 1, 7
Dims = Sequence["int | str"]


def _varint(n: int) -> bytes:
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        out.append(b | (0x80 if n else 0))
        if not n:
            return bytes(out)


def _int(field: int, v: int) -> bytes:
    return _varint(field << 3) + _varint(v)


def _msg(field: int, payload: bytes | str) -> bytes:
    data = payload.encode() if isinstance(payload, str) else payload
    return _varint(field << 3 | 2) + _varint(len(data)) + data


def _value_info(name: str, elem: int, dims: Dims) -> bytes:
    shape = b"".join(_msg(1, _int(1, d) if isinstance(d, int) else _msg(2, d)) for d in dims)
    tensor = _int(1, elem) + _msg(2, shape)
    return _msg(1, name) + _msg(2, _msg(1, tensor))


def identity_model(ios: Sequence[tuple[Dims, int]]) -> bytes:
    """A model of Identity nodes: input ``x{i}`` of shape ``dims`` and element type ``elem``
    passed to output ``y{i}``, for each ``(dims, elem)`` of ``ios``."""
    graph = b"".join(_msg(1, _msg(1, f"x{i}") + _msg(2, f"y{i}") + _msg(4, "Identity")) for i in range(len(ios)))
    graph += _msg(2, "g")
    graph += b"".join(_msg(11, _value_info(f"x{i}", e, d)) for i, (d, e) in enumerate(ios))
    graph += b"".join(_msg(12, _value_info(f"y{i}", e, d)) for i, (d, e) in enumerate(ios))
    return _int(1, 8) + _msg(7, graph) + _msg(8, _int(2, 13))


def write_identity_model(path: Path, ios: Sequence[tuple[Dims, int]]) -> Path:
    path.write_bytes(identity_model(ios))
    return path
