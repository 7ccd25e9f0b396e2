"""Reads a non-interlaced PNG's rows, unfiltered, with the standard library only: shared by the scripts that
make large or steep test inputs (`upsample_png.py`, `steep_tile.py`)."""
import struct
import sys
import zlib


def chunks(data):
    at = 8
    while at < len(data):
        (n,) = struct.unpack(">I", data[at:at + 4])
        yield data[at + 4:at + 8], data[at + 8:at + 8 + n]
        at += 12 + n


def read_rows(path, depth, colour, bpp):
    """(width, height, rows): each row's bytes, unfiltered. Exits with a message unless the PNG has this bit
    `depth` and `colour` type (0 grey, 2 RGB) and is not interlaced; `bpp` is its bytes per pixel."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(f"{path}: not a PNG")
    idat, w, h = b"", 0, 0
    for kind, body in chunks(data):
        if kind == b"IHDR":
            w, h, d, c, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (d, c, interlace) != (depth, colour, 0):
                sys.exit(f"{path}: {depth}-bit, colour type {colour}, non-interlaced PNGs only")
        elif kind == b"IDAT":
            idat += body
    raw = zlib.decompress(idat)
    stride, rows, prev = w * bpp, [], bytearray(w * bpp)
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], (prev[i - bpp] if i >= bpp else 0)
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
