"""Closed submaps as common/map/submap_codec.h writes them (version 1), read back in Python: the
one decoder of the scripts (scripts/ci-floor, scripts/mapmesh/reached.py). Standard library only.

Layout (little-endian): a 36-byte header, magic "MS", u8 version, u8 flags, u32 robot, u32
incarnation, u32 index, f64 opened_s, f64 closed_s, u32 count; then count u32 landmark ids, the
3 + 2 count entries of x (the end pose, then each landmark's mean) as f64, and the lower
triangle of the covariance's Cholesky factor L (p = L L^T), row by row, as f32."""

from __future__ import annotations

import base64
import binascii
import struct
from dataclasses import dataclass

HEADER = struct.Struct("<2sBBIIIddI")
MAGIC = b"MS"
VERSION = 1
MAX_LANDMARKS = 500  # kSubmapCodecMaxLandmarks


@dataclass(frozen=True)
class Submap:
    robot: int
    incarnation: int
    index: int
    opened_s: float
    closed_s: float
    keys: tuple      # the robot's landmark ids, in x's order
    x: tuple         # [end pose x, y, theta; each landmark's x, y] in the submap's frame
    lower: tuple     # L's rows: row r holds its r + 1 entries up to the diagonal

    def covariance(self):
        """p = L L^T as a list of rows."""
        m = len(self.lower)
        return [[sum(self.lower[r][k] * self.lower[c][k] for k in range(min(r, c) + 1)) for c in range(m)]
                for r in range(m)]


def size(count):
    """The bytes of a submap of `count` landmarks."""
    m = 3 + 2 * count
    return HEADER.size + 4 * count + 8 * m + 4 * m * (m + 1) // 2


def header(raw):
    """(robot, incarnation, index, opened_s, closed_s, count) of a submap's header; ValueError
    (one line) when the bytes do not start with one of this codec."""
    if len(raw) < HEADER.size:
        raise ValueError(f"a submap is at least {HEADER.size} bytes, got {len(raw)}")
    magic, version, _flags, robot, incarnation, index, opened, closed, count = HEADER.unpack_from(raw)
    if magic != MAGIC:
        raise ValueError(f"not a submap (magic {magic!r}, expected {MAGIC!r})")
    if version != VERSION:
        raise ValueError(f"submap codec version {version}, expected {VERSION}")
    return robot, incarnation, index, opened, closed, count


def decode(raw):
    """The Submap in `raw` (bytes); ValueError (one line) when it is not exactly one of this codec."""
    robot, incarnation, index, opened, closed, count = header(raw)
    if count > MAX_LANDMARKS:
        raise ValueError(f"a submap of {count} landmarks (at most {MAX_LANDMARKS})")
    if len(raw) != size(count):
        raise ValueError(f"a submap of {count} landmarks is {size(count)} bytes, got {len(raw)}")
    at = HEADER.size
    keys = struct.unpack_from(f"<{count}I", raw, at)
    at += 4 * count
    m = 3 + 2 * count
    x = struct.unpack_from(f"<{m}d", raw, at)
    at += 8 * m
    lower = []
    for r in range(m):
        lower.append(struct.unpack_from(f"<{r + 1}f", raw, at))
        at += 4 * (r + 1)
    return Submap(robot, incarnation, index, opened, closed, keys, x, tuple(lower))


def decode_base64(text):
    """decode() of a submap as checkpoint.json holds it (base64); ValueError when it is not one."""
    try:
        raw = base64.b64decode(text, validate=True)
    except (binascii.Error, TypeError, ValueError) as e:
        raise ValueError(f"not base64: {e}") from None
    return decode(raw)
