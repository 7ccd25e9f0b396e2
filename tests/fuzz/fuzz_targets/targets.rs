//! The fuzz targets' bodies, shared by the cargo-fuzz binaries beside this file and the in-test fuzzer
//! (`tests/cpu/fuzz_parsers.rs`, which runs in `cargo test`). Each takes arbitrary bytes and returns a short
//! outcome: "ok ..." or the error's text with its digits dropped (the in-test fuzzer keeps an input that
//! gives an outcome it has not seen, so later mutations start from deeper in the parser). Any `Err` is
//! fine; a panic, an abort or a hang is a finding.

use std::path::PathBuf;

use clipsat::source::{self, LoadOptions, PngEncoding, RawFormat, RawLayout};

/// A target's body: bytes in, outcome out.
pub(crate) type Target = fn(&[u8]) -> String;

/// Every target, by name, with its body. Names match the cargo-fuzz binaries and the corpus folders.
pub(crate) const TARGETS: [(&str, Target); 15] = [
    ("load_png", load_png),
    ("load_tiff", load_tiff),
    ("load_hgt", load_hgt),
    ("load_asc", load_asc),
    ("load_ehdr", load_ehdr),
    ("load_dted", load_dted),
    ("load_xyz", load_xyz),
    ("load_hgt_full", load_hgt_full),
    ("load_raw", load_raw),
    ("parse_profile", parse_profile),
    ("parse_scene", parse_scene),
    ("load_package", load_package),
    ("load_imagery", load_imagery),
    ("load_imagery_package", load_imagery_package),
    ("load_mosaic", load_mosaic),
];

/// The outcome of a result: "ok" plus `ok`'s text, or the error's kind: its first few plain words, with
/// quoted text, numbers and bytes dropped (they echo the input and would make every input look new).
fn outcome<T>(r: clipsat::Result<T>, ok: impl FnOnce(&T) -> String) -> String {
    match r {
        Ok(v) => format!("ok {}", ok(&v)),
        Err(e) => {
            let text = e.to_string();
            let mut plain = String::new();
            let mut quote = None;
            for c in text.chars() {
                match (quote, c) {
                    (None, '`' | '"' | '\'' | '[' | '(') => {
                        quote = Some(match c {
                            '[' => ']',
                            '(' => ')',
                            q => q,
                        })
                    }
                    (Some(q), _) if c == q => quote = None,
                    (None, _) => plain.push(c),
                    _ => {}
                }
            }
            plain
                .split(|c: char| !c.is_ascii_alphabetic())
                .filter(|w| w.len() >= 3 && !w.bytes().all(|b| b.is_ascii_hexdigit()))
                .take(12)
                .collect::<Vec<_>>()
                .join(" ")
        }
    }
}

/// A folder per process and thread, so parallel tests do not share their files.
fn scratch_dir() -> PathBuf {
    std::env::temp_dir().join(format!(
        "clipsat-fuzz-{}-{:?}",
        std::process::id(),
        std::thread::current().id()
    ))
}

/// Loads `data` as a file called `name` (in a folder per process and thread, so parallel tests do not
/// share it).
fn load_as(name: &str, data: &[u8], opts: &LoadOptions) -> String {
    let dir = scratch_dir();
    let _ = std::fs::create_dir_all(&dir);
    let path: PathBuf = dir.join(name);
    if std::fs::write(&path, data).is_err() {
        return "cannot write".into();
    }
    let r = source::load(&path, opts);
    let _ = std::fs::remove_file(&path);
    let _ = std::fs::remove_dir(&dir);
    outcome(r, |hm| format!("{}x{}", hm.width() > 2, hm.height() > 2))
}

/// A sample limit small enough that huge declared sizes are refused, not allocated; a spacing, so files
/// without one are decoded all the way instead of refused early.
fn small() -> LoadOptions {
    LoadOptions {
        max_samples: 1 << 21,
        spacing: Some(30.0),
        ..LoadOptions::default()
    }
}

/// A PNG file, read with the encoding its length picks (grey, Terrain-RGB, Terrarium). Chunk CRCs are
/// recomputed first (when the length byte is even), so mutations reach the decoder and the channel
/// handling instead of stopping at the checksum.
pub(crate) fn load_png(data: &[u8]) -> String {
    let opts = LoadOptions {
        png_encoding: PngEncoding::ALL[data.len() % 3],
        ..small()
    };
    if data.len().is_multiple_of(2) {
        let mut fixed = data.to_vec();
        fix_png_crcs(&mut fixed);
        return load_as("x.png", &fixed, &opts);
    }
    load_as("x.png", data, &opts)
}

/// Rewrites the CRC of every whole chunk after the signature.
fn fix_png_crcs(png: &mut [u8]) {
    let mut at = 8usize;
    while let Some(len) = png
        .get(at..at + 4)
        .map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as usize)
    {
        let end = at.saturating_add(8).saturating_add(len);
        let Some(body) = png.get(at + 4..end) else {
            return;
        };
        let crc = crc32(body).to_be_bytes();
        let Some(slot) = png.get_mut(end..end + 4) else {
            return;
        };
        slot.copy_from_slice(&crc);
        at = end + 4;
    }
}

/// CRC-32 (ISO-HDLC, as PNG uses), bit by bit.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A TIFF / GeoTIFF file.
pub(crate) fn load_tiff(data: &[u8]) -> String {
    load_as("x.tif", data, &small())
}

/// An SRTM `.hgt` file (any length: most are refused by size).
pub(crate) fn load_hgt(data: &[u8]) -> String {
    load_as("N45E006.hgt", data, &small())
}

/// An ESRI ASCII grid (`.asc`): header lines, then decimal samples.
pub(crate) fn load_asc(data: &[u8]) -> String {
    load_as("x.asc", data, &small())
}

/// An ESRI binary grid: the `.hdr` text up to the first NUL byte, the grid's bytes after it, loaded as
/// a `.bil` or a `.flt` (by the input's length), with or without a spacing given.
pub(crate) fn load_ehdr(data: &[u8]) -> String {
    let (hdr, grid) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    let dir = scratch_dir();
    let _ = std::fs::create_dir_all(&dir);
    let hdr_path = dir.join("x.hdr");
    if std::fs::write(&hdr_path, hdr).is_err() {
        return "cannot write".into();
    }
    let opts = LoadOptions {
        spacing: (data.len() % 4 < 2).then_some(30.0),
        ..small()
    };
    let name = if data.len().is_multiple_of(2) {
        "x.bil"
    } else {
        "x.flt"
    };
    let r = load_as(name, grid, &opts);
    let _ = std::fs::remove_file(&hdr_path);
    let _ = std::fs::remove_dir(&dir);
    r
}

/// Gridded XYZ text (`.xyz`): `x y z` lines.
pub(crate) fn load_xyz(data: &[u8]) -> String {
    load_as("x.xyz", data, &small())
}

/// A DTED cell (`.dt1`): header records, then checksummed columns. When the input's length is even, each
/// record's checksum is recomputed first (records as long as the header's point count says), so
/// mutations reach the heights and the void filling instead of stopping at the checksum.
pub(crate) fn load_dted(data: &[u8]) -> String {
    if data.len().is_multiple_of(2) {
        let mut fixed = data.to_vec();
        fix_dted_checksums(&mut fixed);
        return load_as("x.dt1", &fixed, &small());
    }
    load_as("x.dt1", data, &small())
}

/// Rewrites every whole data record's checksum in a DTED cell (the header's points per column decide the
/// record length).
fn fix_dted_checksums(cell: &mut [u8]) {
    const DATA: usize = 80 + 648 + 2700;
    let Some(rows) = cell
        .get(51..55)
        .and_then(|b| std::str::from_utf8(b).ok())
        .and_then(|s| s.trim().parse::<usize>().ok())
    else {
        return;
    };
    let record = 12 + 2 * rows;
    let Some(body) = cell.get_mut(DATA..) else {
        return;
    };
    for rec in body.chunks_exact_mut(record) {
        let n = record - 4;
        let sum: u32 = rec[..n].iter().map(|&b| u32::from(b)).sum();
        rec[n..].copy_from_slice(&sum.to_be_bytes());
    }
}

/// Bytes of a 1201 x 1201 HGT tile.
const TILE: usize = 1201 * 1201 * 2;

/// The HGT loader past its size check: the input repeated to a whole 3 arc-second tile, so the decoder
/// and the void filling see fuzzed samples.
pub(crate) fn load_hgt_full(data: &[u8]) -> String {
    if data.is_empty() {
        return "empty".into();
    }
    let tile: Vec<u8> = data.iter().copied().cycle().take(TILE).collect();
    load_as("N45E006.hgt", &tile, &small())
}

/// A raw file: the first 5 bytes pick the layout (u16 width, u16 height, u16 or f32), the rest is the file.
pub(crate) fn load_raw(data: &[u8]) -> String {
    let Some((head, body)) = data.split_first_chunk::<5>() else {
        return "short".into();
    };
    let opts = LoadOptions {
        raw: Some(RawLayout {
            width: u32::from(u16::from_le_bytes([head[0], head[1]])),
            height: u32::from(u16::from_le_bytes([head[2], head[3]])),
            format: if head[4] & 1 == 0 {
                RawFormat::U16
            } else {
                RawFormat::F32
            },
        }),
        ..small()
    };
    load_as("x.raw", body, &opts)
}

/// A budget profile's TOML text; what validates must build its meshes and footprint without overflow.
pub(crate) fn parse_profile(data: &[u8]) -> String {
    let Ok(text) = std::str::from_utf8(data) else {
        return "not utf-8".into();
    };
    outcome(clipsat::profile::Profile::parse("fuzz", text), |p| {
        let _ = p.footprint().total();
        let _ = clipsat::plan::mesh::block(p.block_m());
        let _ = clipsat::plan::mesh::skirt(p.clipmap.n + 1);
        let _ = clipsat::plan::mesh::skirt_loops(p.block_m());
        p.height_layers().to_string()
    })
}

/// A scene's TOML text; an accepted scene must answer `needs()` and `features()`.
pub(crate) fn parse_scene(data: &[u8]) -> String {
    let Ok(text) = std::str::from_utf8(data) else {
        return "not utf-8".into();
    };
    outcome(clipsat::shading::scene::Scene::parse("fuzz", text), |s| {
        let _ = s.needs();
        format!("{:?}", s.features().len())
    })
}

/// A terrain package (`clipsat bake`): the header validated on open, then every level decoded when the
/// declared size is small (a bounded coarse level otherwise), as the loader and the tile cache do.
pub(crate) fn load_package(data: &[u8]) -> String {
    let dir = scratch_dir();
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join("x.clipsat");
    if std::fs::write(&path, data).is_err() {
        return "cannot write".into();
    }
    let r = clipsat::package::Package::open(&path).and_then(|p| {
        let h = p.header();
        if u64::from(h.width) * u64::from(h.height) <= 1 << 21 {
            p.to_heightmap().map(|hm| hm.width())
        } else {
            p.coarse_heightmap(1 << 16).map(|hm| hm.width())
        }
    });
    let _ = std::fs::remove_file(&path);
    let _ = std::fs::remove_dir(&dir);
    outcome(r, |w| format!("{}", *w > 2))
}

/// Imagery (`source::imagery`): the bytes as a PNG (even length, chunk CRCs recomputed so mutations reach
/// the decoder) or a JPEG (odd length), read and placed over a 65 x 65 grid under a small texel limit.
pub(crate) fn load_imagery(data: &[u8]) -> String {
    use clipsat::source::imagery::{Extent, Imagery, ImageryOptions};
    let dir = scratch_dir();
    let _ = std::fs::create_dir_all(&dir);
    let (name, bytes) = if data.len().is_multiple_of(2) {
        let mut fixed = data.to_vec();
        fix_png_crcs(&mut fixed);
        ("x.png", fixed)
    } else {
        ("x.jpg", data.to_vec())
    };
    let path = dir.join(name);
    if std::fs::write(&path, bytes).is_err() {
        return "cannot write".into();
    }
    let opts = ImageryOptions {
        max_texels: 1 << 21,
        ..ImageryOptions::default()
    };
    let r = Imagery::load(&path, &Extent::of_grid(65, 65, 30.0, (0.0, 0.0)), &opts);
    let _ = std::fs::remove_file(&path);
    let _ = std::fs::remove_dir(&dir);
    outcome(r, |im| format!("{}", im.size().0 > 2))
}

/// An imagery package (`package::imagery`) from bytes: the header checked, then every tile of a small
/// one decoded (CRCs and JPEG; a residual tile with its parent).
pub(crate) fn load_imagery_package(data: &[u8]) -> String {
    use clipsat::package::imagery::ImageryPackage;
    let r = ImageryPackage::from_bytes(std::path::Path::new("x.clipsat-imagery"), data.to_vec())
        .and_then(|p| {
            let h = p.header().clone();
            let mut tile = vec![0u8; 3 * h.tile as usize * h.tile as usize];
            let mut parent = tile.clone();
            let mut decoded = 0;
            if h.texels() <= 1 << 21 {
                for (level, l) in h.levels.iter().enumerate() {
                    for ty in 0..l.tiles_y {
                        for tx in 0..l.tiles_x {
                            p.decode_texels(level, tx, ty, &mut tile, &mut parent)?;
                            decoded += 1;
                        }
                    }
                }
            }
            Ok(decoded)
        });
    outcome(r, |n| format!("{}", *n > 0))
}

/// A tile mosaic's list of tiles (`.txt`, odd length) or GDAL VRT (`.vrt`, even length), beside the two
/// tiles it may name, `a.tif` and `b.tif` (4 x 4 GeoTIFF samples at 1", sharing a column), loaded whole.
pub(crate) fn load_mosaic(data: &[u8]) -> String {
    let dir = scratch_dir().join("mosaic");
    let _ = std::fs::create_dir_all(&dir);
    let step = 1.0 / 3600.0;
    for (name, west) in [("a.tif", 11.0), ("b.tif", 11.0 + 3.0 * step)] {
        if std::fs::write(dir.join(name), geotiff(4, 4, (west, 58.0), step)).is_err() {
            return "cannot write".into();
        }
    }
    let name = if data.len().is_multiple_of(2) {
        "x.vrt"
    } else {
        "x.txt"
    };
    let path = dir.join(name);
    if std::fs::write(&path, data).is_err() {
        return "cannot write".into();
    }
    let r = source::load(&path, &small());
    for file in ["x.vrt", "x.txt", "a.tif", "b.tif"] {
        let _ = std::fs::remove_file(dir.join(file));
    }
    let _ = std::fs::remove_dir(&dir);
    let _ = std::fs::remove_dir(scratch_dir());
    outcome(r, |hm| format!("{}x{}", hm.width() > 2, hm.height() > 2))
}

/// A little-endian int16 GeoTIFF of `w` x `h` samples (w, h < 2^16), one strip: geographic (EPSG 4326),
/// pixel-is-point, sample (0, 0) at `first` (longitude, latitude), `step` degrees apart.
fn geotiff(w: u16, h: u16, first: (f64, f64), step: f64) -> Vec<u8> {
    const ENTRIES: u16 = 13;
    let data = 8 + 2 + 12 * u32::from(ENTRIES) + 4;
    let (scale, tie, keys) = (data, data + 24, data + 72);
    let strip = keys + 32;
    // (tag, type: 3 SHORT, 4 LONG, 12 DOUBLE, count, value or offset)
    let entries: [(u16, u16, u32, u32); ENTRIES as usize] = [
        (256, 3, 1, u32::from(w)),
        (257, 3, 1, u32::from(h)),
        (258, 3, 1, 16),
        (259, 3, 1, 1),
        (262, 3, 1, 1),
        (273, 4, 1, strip),
        (277, 3, 1, 1),
        (278, 3, 1, u32::from(h)),
        (279, 4, 1, 2 * u32::from(w) * u32::from(h)),
        (339, 3, 1, 2),
        (33550, 12, 3, scale),
        (33922, 12, 6, tie),
        (34735, 3, 16, keys),
    ];
    let mut b = b"II*\0".to_vec();
    b.extend_from_slice(&8u32.to_le_bytes());
    b.extend_from_slice(&ENTRIES.to_le_bytes());
    for (tag, kind, count, value) in entries {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&kind.to_le_bytes());
        b.extend_from_slice(&count.to_le_bytes());
        b.extend_from_slice(&value.to_le_bytes());
    }
    b.extend_from_slice(&0u32.to_le_bytes());
    for v in [step, step, 0.0, 0.0, 0.0, 0.0, first.0, first.1, 0.0] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    // Model type geographic, raster type pixel-is-point, WGS 84.
    let geokeys: [u16; 16] = [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 2, 2048, 0, 1, 4326];
    for k in geokeys {
        b.extend_from_slice(&k.to_le_bytes());
    }
    for i in 0..u32::from(w) * u32::from(h) {
        b.extend_from_slice(&u16::try_from(i * 7 % 300).unwrap_or(0).to_le_bytes());
    }
    b
}
