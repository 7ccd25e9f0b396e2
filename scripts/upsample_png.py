#!/usr/bin/env python3
"""A large test image from a small one: an 8-bit RGB, non-interlaced PNG with every texel repeated K x K,
written row by row (docs/measurements.md, "Imagery's out-of-core bake and memory"). Standard library only.
Usage: scripts/upsample_png.py IN.png K OUT.png"""
import struct
import sys
import zlib


def chunks(data):
    at = 8
    while at < len(data):
        (n,) = struct.unpack(">I", data[at:at + 4])
        yield data[at + 4:at + 8], data[at + 8:at + 8 + n]
        at += 12 + n


def read_rgb8(path):
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(f"{path}: not a PNG")
    idat = b""
    for kind, body in chunks(data):
        if kind == b"IHDR":
            w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (depth, colour, interlace) != (8, 2, 0):
                sys.exit(f"{path}: 8-bit RGB, non-interlaced PNGs only")
        elif kind == b"IDAT":
            idat += body
    raw = zlib.decompress(idat)
    stride, rows, prev = w * 3, [], bytearray(w * 3)
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - 3] if i >= 3 else 0
            b, c = prev[i], (prev[i - 3] if i >= 3 else 0)
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line))
        prev = line
    return w, h, rows


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
