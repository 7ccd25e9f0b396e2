#!/usr/bin/env python3
"""Package codec against JPEG XL lossless, LERC and zstd (docs/package-codec.md, the measurement table).

For each shared terrain and each error bound E, the grid the package stores at level 0 (k = round(h / 2E),
the quantum q = 2E) is coded by:
  - JPEG XL, lossless, effort 9 (libjxl through Python's `imagecodecs`), level 0 only; its decode CPU time
    on one thread (best of 10);
  - LERC with max error E on the heights in metres;
  - zstd level 19 of the row deltas of k (int16 where they fit, else int32).
and, with --clipsat BIN, the package pyramid's bytes per level-0 sample from `BIN bake T --max-error E --json`.
B/sample is bytes over level-0 samples. Optional tooling, not part of the tests: it installs numpy and
imagecodecs with pip when they are missing.

Usage: scripts/codec_compare.py [--data DIR] [--clipsat BIN] [--errors 0.5,2] [--json OUT]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

try:
    import imagecodecs
    import numpy as np
except ImportError:
    subprocess.check_call([sys.executable, "-m", "pip", "install", "--quiet", "numpy", "imagecodecs"])
    import imagecodecs
    import numpy as np

# (file, spacing for PNGs, the default error bound the package picks: lossless on lattice data).
TERRAINS = [
    ("srtm_bigtujunga30m_utm11.tif", None, 0.5),
    ("n07_w006_3arc_v2.tif", None, 0.5),
    ("N57E011.hgt", None, 0.5),
    ("ps_height_1k.png", 160, 0.05),
    ("lidar_pkg_dem_1m_400x400.tif", None, 0.005),
    ("aletsch_200m.tif", None, 0.005),
]


def heights(path):
    """Level 0 in metres, float64, row 0 north (as the package stores it)."""
    if path.endswith(".hgt"):
        raw = np.fromfile(path, dtype=">i2")
        n = int(round(len(raw) ** 0.5))
        return raw.reshape(n, n).astype(np.float64)
    a = imagecodecs.imread(path)
    if path.endswith(".png"):
        return a.astype(np.float64) * 0.1  # u16 decimetres
    return a.astype(np.float64)


def jxl(k):
    """JPEG XL lossless effort 9 of the integer grid k: (bytes, decode ns/sample on one thread) or None."""
    lo = k.min()
    u = k - lo
    if u.max() >= 1 << 16:
        return None  # beyond 16 bits: not measured
    data = imagecodecs.jpegxl_encode(u.astype(np.uint16), lossless=True, effort=9, numthreads=1)
    # CPU time of this process (one decoding thread), best of 10: steadier than wall time on a shared
    # machine.
    best = float("inf")
    for _ in range(10):
        t = time.process_time()
        back = imagecodecs.jpegxl_decode(data, numthreads=1)
        best = min(best, time.process_time() - t)
    assert np.array_equal(back.astype(np.int64), u), "JPEG XL is not lossless here"
    return len(data), best * 1e9 / k.size


def lerc(h, e):
    data = imagecodecs.lerc_encode(h.astype(np.float32), level=e)
    back = imagecodecs.lerc_decode(data)
    assert np.abs(back.astype(np.float64) - h).max() <= e * (1 + 1e-6) + 1e-3
    return len(data)


def zstd_rows(k):
    d = np.diff(k, axis=1, prepend=0)
    t = np.int16 if np.abs(d).max() < 1 << 15 else np.int32
    return len(imagecodecs.zstd_encode(d.astype(t).tobytes(), level=19))


def package(binary, path, spacing, e):
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [binary, "bake", path, "--max-error", str(e), "--out", os.path.join(tmp, "p.clipsat"), "--json"]
        if spacing:
            cmd += ["--spacing", str(spacing)]
        r = json.loads(subprocess.check_output(cmd))
        return r["pyramid_bytes_per_sample"], r["max_error"]


def main():
    ap = argparse.ArgumentParser()
    # The folder `clipsat::data_dir()` reads: CLIPSAT_DATA, else the project's default beside it.
    default = os.environ.get("CLIPSAT_DATA") or os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data")
    ap.add_argument("--data", default=default)
    ap.add_argument("--clipsat", help="a clipsat binary: adds the package column")
    ap.add_argument("--errors", default="default,2", help="comma-separated E in metres; `default`: lossless")
    ap.add_argument("--json", help="also write the rows as JSON here")
    a = ap.parse_args()
    rows = []
    print("| terrain | E m | package | JPEG XL e9 lossless | JXL decode ns/sample | LERC | zstd-19 row deltas |")
    print("|---|---|---|---|---|---|---|")
    for name, spacing, default in TERRAINS:
        path = os.path.join(a.data, name)
        if not os.path.isfile(path):
            print(f"skipping {name}: missing", file=sys.stderr)
            continue
        h = heights(path)
        n = h.size
        for es in a.errors.split(","):
            e = default if es == "default" else float(es)
            k = np.round(h / (2 * e)).astype(np.int64)
            row = {"terrain": name, "max_error": e, "samples": n}
            j = jxl(k) if es == "default" else None
            row["jxl_b"] = j and j[0] / n
            row["jxl_ns"] = j and j[1]
            row["lerc_b"] = lerc(h, e) / n
            row["zstd_b"] = zstd_rows(k) / n
            if a.clipsat:
                row["package_b"], row["package_max_error"] = package(a.clipsat, path, spacing, e)
            rows.append(row)
            f = lambda v, p=3: "-" if v is None else f"{v:.{p}f}"
            print(f"| {name} | {e} | {f(row.get('package_b'))} | {f(row['jxl_b'])} | {f(row['jxl_ns'], 1)} "
                  f"| {f(row['lerc_b'])} | {f(row['zstd_b'])} |", flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
