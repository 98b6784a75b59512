"""How a result document is stored: its float arrays as binary, predicted and compressed (issue 27).

A result is mostly long arrays of floats (an intercept scan is 16,161 pairs: 441 of the preset's 443 kB
of JSON).  As JSON text those cost about 20 bytes a number, and a general compressor gets only 2.4x
(zlib) to 3.5x (xz) out of them: the digits of a float are close to random.  The numbers are
samples of smooth curves, though, so this module stores each long float array as float64 and
keeps, instead of the values, their finite differences of order 0 to 3 on the integer view of the
bits (a polynomial predictor, as in FPZIP; chosen per array by the smallest residuals), split into
eight byte planes (the Blosc/HDF5 "shuffle": the sign, exponent and high mantissa bytes of
neighbours are alike), and zlib-compresses the lot.  Bytes stored per preset, JSON text -> now (ratio;
zlib of the JSON alone in brackets): intercept 442,564 -> 38,101 (11.6x; 2.4x), reentry Betts
105,581 -> 29,367 (3.6x; 2.0x), robust (10,000 samples) 2,579,720 -> 815,884 (3.2x; 2.1x),
midcourse 17,976 -> 6,130 (2.9x), ocp brachistochrone 6,465 -> 2,403 (2.7x).  Reading one back takes a fraction of
``json.loads`` of its text (intercept 4 ms against 33 ms): arrays of one length are undone together.

Everything is exact: integer differences wrap around and are undone by the same number of cumulative
sums, so each float comes back bit for bit, and the API's JSON is the same document byte for byte
(tests/integration/test_retention_http.py).

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


_FLOAT_OR_NONE = {float, type(None)}


def _packable(value) -> bool:
    # the types in C (map/set), not a Python loop: a robust result has 1.3 million numbers
    if not isinstance(value, list) or len(value) < MIN_PACKED:
        return False
    kinds = set(map(type, value))
    return float in kinds and kinds <= _FLOAT_OR_NONE


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


def _residuals(bits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``bits`` (arrays of one length), the order (0..MAX_ORDER) of differences with the
    smallest residuals, and those residuals."""
    candidates, costs, r = [], [], bits
    for order in range(MAX_ORDER + 1):
        if order:
            r = np.concatenate([r[:, :1], np.diff(r, axis=1)], axis=1)  # int64 wraps; cumsum undoes it exactly
        candidates.append(r)
        costs.append(np.log2(np.abs(r[:, 1:].astype(np.float64)) + 1.0).sum(axis=1))
    orders = np.argmin(np.stack(costs), axis=0)
    return orders, np.stack(candidates)[orders, np.arange(len(orders))]


def _shuffled(rows: np.ndarray) -> bytes:
    """Each row's eight byte planes, row after row (the layout :func:`decode` reads)."""
    k, n = rows.shape
    return np.ascontiguousarray(rows.astype("<i8").view(np.uint8).reshape(k, n, 8).transpose(0, 2, 1)).tobytes()


def encode(doc: dict) -> tuple[bytes, str]:
    """``(packed bytes, encoding)`` of a result document (JSON-ready: dicts, lists, str, int, float, None)."""
    arrays: list = []
    skeleton = _split(doc, [], arrays)
    by_length: dict[int, list] = {}
    for path, values in arrays:
        by_length.setdefault(len(values), []).append((path, values))
    specs, blobs = [], []
    # arrays of one length are predicted together, and written grouped by (length, order) so that
    # decode undoes a whole group with one cumsum
    for n, group in by_length.items():
        a = np.array([values for _, values in group], dtype="<f8")  # None -> NaN
        nulls = np.isnan(a)
        kept = [i for i, (_, values) in enumerate(group) if int(nulls[i].sum()) == values.count(None)]
        if len(kept) < len(group):  # a real NaN (JSON cannot carry one): that list stays in the skeleton
            for i in set(range(len(group))) - set(kept):
                path, values = group[i]
                if path:
                    _put(skeleton, path, values)
                else:
                    skeleton = values
            group, a, nulls = [group[i] for i in kept], a[kept], nulls[kept]
            if not group:
                continue
        bits = a.view("<i8").copy()
        bits[nulls] = np.int64(_NULL_BITS.astype(np.int64))
        orders, residuals = _residuals(bits)
        for order in np.unique(orders).tolist():
            rows = np.flatnonzero(orders == order)
            specs += [[group[i][0], n, order, bool(nulls[i].any())] for i in rows.tolist()]
            blobs.append(_shuffled(residuals[rows]))
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
    if packed is None:
        raise ValueError(f"result encoded as {encoding!r} without its packed bytes")
    raw = zlib.decompress(packed)
    (n_header,) = _HEADER.unpack_from(raw)
    header = json.loads(raw[_HEADER.size:_HEADER.size + n_header])
    doc, specs, at = header["doc"], header["arrays"], _HEADER.size + n_header
    null_bits = np.int64(_NULL_BITS.astype(np.int64))
    i = 0
    while i < len(specs):  # a run of arrays of one length and order: one block, one cumsum
        _, n, order, _ = specs[i]
        j = i + 1
        while j < len(specs) and specs[j][1] == n and specs[j][2] == order:
            j += 1
        k = j - i
        planes = np.frombuffer(raw, dtype=np.uint8, count=8 * n * k, offset=at).reshape(k, 8, n)
        bits = np.ascontiguousarray(planes.transpose(0, 2, 1)).view("<i8").reshape(k, n)
        at += 8 * n * k
        for _ in range(order):
            bits = np.cumsum(bits, axis=1, dtype=np.int64)
        rows: list[list[float | None]] = bits.view("<f8").tolist()
        for (path, _, _, has_nulls), row_bits, values in zip(specs[i:j], bits, rows):
            if has_nulls:
                for m in np.flatnonzero(row_bits == null_bits).tolist():
                    values[m] = None
            if not path:
                return values  # the whole document was one array
            _put(doc, path, values)
        i = j
    return doc
