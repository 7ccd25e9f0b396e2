#!/usr/bin/env python3
"""A large test image from a small one: an 8-bit RGB, non-interlaced PNG with every texel repeated K x K,
written row by row (docs/measurements.md, "Imagery's out-of-core bake and memory"). Standard library only.
Usage: scripts/upsample_png.py IN.png K OUT.png"""
import os
import struct
import sys
import zlib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from png_rows import read_rows  # noqa: E402


def read_rgb8(path):
    return read_rows(path, 8, 2, 3)


def chunk(kind, body):
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def main():
    src, k, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    w, h, rows = read_rgb8(src)
    with open(out, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w * k, h * k, 8, 2, 0, 0, 0)))
        z = zlib.compressobj(1)
        for row in rows:
            big = b"\x00" + b"".join(row[i:i + 3] * k for i in range(0, len(row), 3))
            for _ in range(k):
                c = z.compress(big)
                if c:
                    f.write(chunk(b"IDAT", c))
        f.write(chunk(b"IDAT", z.flush()))
        f.write(chunk(b"IEND", b""))


if __name__ == "__main__":
    main()
