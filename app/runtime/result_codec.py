"""How a result document is stored: its float arrays as binary, predicted and compressed (issue 27).

A result is mostly long arrays of floats (an intercept scan is 16,161 pairs: 441 of its 443 kB of
JSON).  As JSON text those cost about 20 bytes a number, and a general compressor gets only 2.4x
(zlib) to 3.5x (xz) out of them: the digits of a float are close to random.  The numbers are
samples of smooth curves, though, so this module stores each long float array as float64 and
keeps, instead of the values, their finite differences of order 0 to 3 on the integer view of the
bits (a polynomial predictor, as in FPZIP; chosen per array by the smallest residuals), split into
eight byte planes (the Blosc/HDF5 "shuffle": the sign, exponent and high mantissa bytes of
neighbours are alike), and zlib-compresses the lot: the intercept preset's result goes from 442,564
to about 28,000 bytes.  Everything is exact: integer differences wrap around and are undone by the
same number of cumulative sums, so each float comes back bit for bit, and the API's JSON is the
same document byte for byte (tests/integration/test_retention_http.py).

What is packed: a list (at any depth) of at least :data:`MIN_PACKED` elements, every one a Python
``float`` other than NaN, or ``None`` (kept as a mask), and at least one float.  Lists of ints,
strings or mixed types, and short lists, stay in the JSON skeleton as they are, so an ``int`` never
comes back as ``1.0``.  The skeleton holds ``null`` where a packed array was, and the header lists
each array by its path (keys and indexes), so no marker value can be confused with user data.

Encodings (``job_results.encoding``): ``f64d+zlib`` (this layout), and ``NULL`` for rows written
before revision 0006, whose JSON is in ``job_results.data``.  A new layout gets a new name; every
name ever written stays readable here (migration 0006's downgrade uses :func:`decode` too).
"""
from __future__ import annotations

import json
import struct
import zlib

import numpy as np

ENCODING = "f64d+zlib"
MIN_PACKED = 16
MAX_ORDER = 3
ZLIB_LEVEL = 6  # level 9 saved under 1% here for 40% more time
_NULL_BITS = np.uint64(0x7FF8_0000_0000_0DEF)  # a NaN payload of our own, masked back to None (never a real NaN)
_HEADER = struct.Struct(">I")


def _packable(value) -> bool:
    if not isinstance(value, list) or len(value) < MIN_PACKED:
        return False
    seen_float = False
    for x in value:
        if type(x) is float:
            if x != x:  # NaN: JSON cannot carry it; leave such a list as it is
                return False
            seen_float = True
        elif x is not None:
            return False
    return seen_float


def _key(k) -> str:
    # the key as JSON writes it (1 -> "1", True -> "true"), so a path finds it in the parsed skeleton
    return k if isinstance(k, str) else next(iter(json.loads(json.dumps({k: 0}))))


def _split(doc, path: list, arrays: list):
    """The skeleton of ``doc`` with packable lists replaced by None; ``arrays`` gets (path, list)."""
    if isinstance(doc, dict):
        return {_key(k): _split(v, [*path, _key(k)], arrays) for k, v in doc.items()}
    if isinstance(doc, (list, tuple)):
        if _packable(doc):
            arrays.append((path, doc))
            return None
        return [_split(v, [*path, i], arrays) for i, v in enumerate(doc)]
    return doc


def _residuals(bits: np.ndarray) -> tuple[int, np.ndarray]:
    """The order (0..MAX_ORDER) of differences with the smallest residuals, and those residuals."""
    best, best_cost, r = 0, None, bits
    for order in range(MAX_ORDER + 1):
        if order:
            r = np.concatenate([r[:1], np.diff(r)])  # int64 wraps around; cumsum undoes it exactly
        cost = float(np.log2(np.abs(r[1:].astype(np.float64)) + 1.0).sum())
        if best_cost is None or cost < best_cost:
            best, best_cost, kept = order, cost, r
    return best, kept


def _shuffle(a: np.ndarray) -> bytes:
    return a.view(np.uint8).reshape(-1, 8).T.tobytes()


def _unshuffle(raw: bytes, n: int) -> np.ndarray:
    return np.frombuffer(raw, dtype=np.uint8).reshape(8, n).T.copy().view("<i8").reshape(n)


def encode(doc: dict) -> tuple[bytes, str]:
    """``(packed bytes, encoding)`` of a result document (JSON-ready: dicts, lists, str, int, float, None)."""
    arrays: list = []
    skeleton = _split(doc, [], arrays)
    specs, blobs = [], []
    for path, values in arrays:
        nulls = [i for i, x in enumerate(values) if x is None]
        a = np.array([float("nan") if x is None else x for x in values], dtype="<f8")
        bits = a.view("<i8").copy()
        if nulls:
            bits[nulls] = _NULL_BITS.astype(np.int64)
        order, residuals = _residuals(bits)
        specs.append([path, len(values), order, bool(nulls)])
        blobs.append(_shuffle(residuals.astype("<i8")))
    header = json.dumps({"doc": skeleton, "arrays": specs}, separators=(",", ":"), allow_nan=True).encode()
    return zlib.compress(b"".join([_HEADER.pack(len(header)), header, *blobs]), ZLIB_LEVEL), ENCODING


def _put(skeleton, path: list, value) -> None:
    node = skeleton
    for part in path[:-1]:
        node = node[part]
    node[path[-1]] = value


def decode(packed: bytes | None, encoding: str | None, data=None):
    """The result document of a stored row: ``packed`` in ``encoding``, or ``data`` when the row
    predates compression (``encoding`` None)."""
    if encoding is None:
        return data
    if encoding != ENCODING:
        raise ValueError(f"unknown result encoding {encoding!r}")
    raw = zlib.decompress(packed)
    (n_header,) = _HEADER.unpack_from(raw)
    header = json.loads(raw[_HEADER.size:_HEADER.size + n_header])
    doc, at = header["doc"], _HEADER.size + n_header
    for path, n, order, has_nulls in header["arrays"]:
        bits = _unshuffle(raw[at:at + 8 * n], n)
        at += 8 * n
        for _ in range(order):
            bits = np.cumsum(bits, dtype=np.int64)
        values = bits.view("<f8").tolist()
        if has_nulls:
            for i in np.flatnonzero(bits == _NULL_BITS.astype(np.int64)).tolist():
                values[i] = None
        if not path:
            return values  # the whole document was one array
        _put(doc, path, values)
    return doc
