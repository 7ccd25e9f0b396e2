#!/usr/bin/env python3
"""KTX2 with Basis Universal against the imagery package's tiles (docs/guide.md "Imagery", the format choice).

For each shared image, Basis Universal's `basisu` tool (github.com/BinomialLLC/basis_universal, built by
the caller: not part of the project or its tests) encodes a KTX2 file in ETC1S (at its default quality and at
-quality 100) and in UASTC (with Zstandard supercompression, with and without RDO), then unpacks each into the
formats a GPU takes (RGBA8, BC1, ETC1, BC7). Per file: bytes per texel and PSNR over RGB against the source
after transcoding, beside a whole-image JPEG at quality 90 (4:2:0, libjpeg through imagecodecs) and, with
--clipsat BIN, the imagery package's level 0 (`BIN bake ... --imagery I --json`). It installs numpy and
imagecodecs with pip when they are missing.

Usage: scripts/ktx2_compare.py --basisu PATH [--data DIR] [--clipsat BIN]
"""

import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile

try:
    import imagecodecs
    import numpy as np
except ImportError:
    subprocess.check_call([sys.executable, "-m", "pip", "install", "--quiet", "numpy", "imagecodecs"])
    import imagecodecs
    import numpy as np

# (image, its heights and their reading options for the package's bake).
IMAGES = [
    ("imagery/ps_texture_1k.png", "ps_height_1k.png", ["--spacing", "160"]),
    ("imagery/gcanyon_color_1024.png", "imagery/gcanyon_elev_1200.png", ["--spacing", "60", "--height-scale", "10"]),
]

MODES = [
    ("ETC1S", []),
    ("ETC1S -quality 100", ["-quality", "100"]),
    ("UASTC + zstd", ["-uastc", "-ktx2_zstandard_level", "19"]),
    ("UASTC RDO 1.0 + zstd", ["-uastc", "-uastc_rdo_l", "1.0", "-ktx2_zstandard_level", "19"]),
]


def psnr(a, b):
    mse = np.mean((a[..., :3].astype(np.float64) - b[..., :3].astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--basisu", required=True)
    ap.add_argument("--data", default=os.environ.get("CLIPSAT_DATA", "../shared/data"))
    ap.add_argument("--clipsat")
    args = ap.parse_args()
    print("| image | file | bytes/texel | PSNR as RGBA8 | as BC1 | as ETC1 | as BC7 |")
    print("|---|---|---|---|---|---|---|")
    for name, heights, opts in IMAGES:
        path = os.path.abspath(os.path.join(args.data, name))
        src = imagecodecs.imread(path)[..., :3]
        texels = src.shape[0] * src.shape[1]
        jpeg = imagecodecs.jpeg8_encode(src, level=90)
        back = imagecodecs.jpeg8_decode(jpeg)
        short = os.path.basename(name)
        print(f"| {short} | JPEG q90 4:2:0 | {len(jpeg) / texels:.3f} | {psnr(src, back):.2f} | | | |")
        with tempfile.TemporaryDirectory() as tmp:
            if args.clipsat:
                out = subprocess.run(
                    [args.clipsat, "bake", os.path.join(args.data, heights), *opts, "--imagery", path,
                     "--out", os.path.join(tmp, "p.clipsat"), "--json"],
                    check=True, capture_output=True, text=True).stdout
                r = json.loads(out)["imagery"]
                print(f"| {short} | clipsat package, level 0 (all levels) | {r['level0_bytes_per_texel']:.3f} "
                      f"({r['bytes_per_texel']:.3f}) | {r['psnr_db']:.2f} | | | |")
            for label, flags in MODES:
                ktx = os.path.join(tmp, "t.ktx2")
                subprocess.run([args.basisu, "-ktx2", *flags, path, "-output_file", ktx],
                               check=True, capture_output=True, cwd=tmp)
                size = os.path.getsize(ktx)
                unpack = os.path.join(tmp, "u")
                os.makedirs(unpack, exist_ok=True)
                subprocess.run([args.basisu, "-unpack", ktx, "-no_ktx"], check=True, capture_output=True,
                               cwd=unpack)
                found = {}
                for fmt in ("RGBA32", "BC1_RGB", "ETC1_RGB", "BC7_RGBA"):
                    files = sorted(glob.glob(os.path.join(unpack, f"*_unpacked_rgb_{fmt}_*.png")))
                    if files:
                        found[fmt] = psnr(src, imagecodecs.imread(files[0]))
                cells = " | ".join(f"{found[k]:.2f}" if k in found else "-"
                                   for k in ("RGBA32", "BC1_RGB", "ETC1_RGB", "BC7_RGBA"))
                print(f"| {short} | KTX2 {label} | {size / texels:.3f} | {cells} |")
                for f in glob.glob(os.path.join(unpack, "*")):
                    os.remove(f)


if __name__ == "__main__":
    sys.exit(main())
