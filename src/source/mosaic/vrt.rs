//! Stage 0, the source: a GDAL VRT mosaic (`gdalbuildvrt`'s XML) read as a list of tiles (docs/guide.md
//! "Tile mosaics"). Its sources are placed by their own georeference, as every mosaic's tiles are, and
//! each source's place in the VRT is checked against it: a VRT that crops, moves, rescales or derives its
//! sources' values is refused, naming what it does, since the mosaic would not draw what GDAL reads.
//! Where tiles of one resolution overlap, GDAL paints later sources over earlier ones, so the mosaic reads
//! them last first (its rule: the finest tile wins, then the first given).

use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// One source of the VRT's band, as the VRT places it.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Source {
    /// The tile's file.
    pub(super) path: PathBuf,
    /// Its rectangle in the VRT's pixels: x offset, y offset, columns, rows.
    pub(super) dst: [f64; 4],
}

/// A VRT's sources in the order the mosaic reads them, and its geotransform.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Vrt {
    /// GDAL's geotransform: x0, pixel width, row rotation, y0, column rotation, pixel height (negative
    /// for north up).
    pub(super) transform: [f64; 6],
    /// Last in the VRT first.
    pub(super) sources: Vec<Source>,
}

impl Vrt {
    /// Reads and checks the VRT at `path`: one band, plain sources (`SimpleSource`, or `ComplexSource`
    /// with no scaling or lookup table) of the whole of each tile's band 1, a north-up geotransform.
    pub(super) fn read(path: &Path) -> Result<Self> {
        let bad = |reason: String| Error::format(path, format!("GDAL VRT: {reason}"));
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, "cannot read", e))?;
        let text = String::from_utf8(bytes).map_err(|_| {
            Error::format(path, "a GDAL VRT that is not UTF-8 text (GDAL writes UTF-8): save it as UTF-8")
        })?;
        let doc = roxmltree::Document::parse(&text).map_err(|e| bad(format!("not XML: {e}")))?;
        let root = doc.root_element();
        if root.tag_name().name() != "VRTDataset" {
            return Err(bad(format!("the root is <{}>, not <VRTDataset>", root.tag_name().name())));
        }
        if let Some(kind) = root.attribute("subClass") {
            return Err(bad(format!(
                "a {kind} resamples its sources; build a plain mosaic with gdalbuildvrt"
            )));
        }
        let transform = child_text(root, "GeoTransform")
            .ok_or_else(|| bad("no <GeoTransform>: a mosaic is placed by it".into()))?;
        // Finite: a NaN compares false with every bound, and had passed every check on the VRT's place.
        let numbers: Vec<f64> = transform
            .split(',')
            .filter_map(|v| v.trim().parse().ok())
            .filter(|v: &f64| v.is_finite())
            .collect();
        let transform: [f64; 6] = numbers.try_into().map_err(|_| {
            bad(format!("<GeoTransform> `{}` is not six finite numbers", transform.trim()))
        })?;
        if transform[2] != 0.0 || transform[4] != 0.0 || transform[1] <= 0.0 || transform[5] >= 0.0 {
            return Err(bad(format!(
                "<GeoTransform> {transform:?} is rotated or not north up"
            )));
        }
        let bands: Vec<_> = root.children().filter(|n| n.has_tag_name("VRTRasterBand")).collect();
        let [band] = bands.as_slice() else {
            return Err(bad(format!(
                "{} bands: a DEM mosaic has one (<VRTRasterBand>)",
                bands.len()
            )));
        };
        if let Some(kind) = band.attribute("subClass") {
            return Err(bad(format!("a {kind} band derives its values; a mosaic reads plain sources")));
        }
        let base = path.parent().unwrap_or(Path::new(""));
        let mut sources = Vec::new();
        for s in band.children().filter(roxmltree::Node::is_element) {
            let kind = s.tag_name().name();
            match kind {
                "SimpleSource" | "ComplexSource" => {}
                k if k.ends_with("Source") => {
                    return Err(bad(format!(
                        "a <{k}> filters or averages its tile; a mosaic reads SimpleSource and \
                         ComplexSource"
                    )))
                }
                _ => continue,
            }
            for (tag, identity) in [("ScaleOffset", 0.0), ("ScaleRatio", 1.0)] {
                if let Some(v) = child_text(s, tag) {
                    if v.trim().parse::<f64>().ok() != Some(identity) {
                        return Err(bad(format!(
                            "a source with <{tag}>{}</{tag}> rescales its heights; rescale the tile",
                            v.trim()
                        )));
                    }
                }
            }
            // GDAL maps a ComplexSource's values through each of these (an exponent between SrcMin..SrcMax
            // and DstMin..DstMax, a palette's component); a mosaic had read the raw values.
            for tag in ["LUT", "Exponent", "ColorTableComponent"] {
                if s.children().any(|c| c.has_tag_name(tag)) {
                    return Err(bad(format!(
                        "a source with a <{tag}> maps its heights; a mosaic reads them as they are"
                    )));
                }
            }
            let file = s
                .children()
                .find(|c| c.has_tag_name("SourceFilename"))
                .ok_or_else(|| bad(format!("a <{kind}> without <SourceFilename>")))?;
            let name = file.text().unwrap_or_default().trim();
            if name.starts_with("/vsi") {
                return Err(bad(format!(
                    "source `{name}` is in a GDAL virtual file system; give the tile's own file"
                )));
            }
            let tile = if file.attribute("relativeToVRT") == Some("1") {
                base.join(name)
            } else {
                PathBuf::from(name)
            };
            if let Some(b) = child_text(s, "SourceBand") {
                if b.trim() != "1" {
                    return Err(bad(format!("source `{name}` reads band {}: a DEM tile's is 1", b.trim())));
                }
            }
            let dst = rect(s, "DstRect").ok_or_else(|| {
                bad(format!("source `{name}` has no <DstRect> of four finite numbers"))
            })?;
            let src = rect(s, "SrcRect");
            if src.is_none() && s.children().any(|c| c.has_tag_name("SrcRect")) {
                return Err(bad(format!(
                    "source `{name}` has a <SrcRect> that is not four finite numbers"
                )));
            }
            if let Some(src) = src {
                if src[0] != 0.0 || src[1] != 0.0 {
                    return Err(bad(format!(
                        "source `{name}` is cropped (SrcRect from {}, {}): a mosaic reads whole tiles",
                        src[0], src[1]
                    )));
                }
            }
            sources.push(Source { path: tile, dst });
        }
        if sources.is_empty() {
            return Err(bad("a band with no source tile".into()));
        }
        sources.reverse();
        Ok(Self { transform, sources })
    }

    /// Checks that source `i`'s rectangle in the VRT is where its tile's own georeference puts it: the
    /// tile's pixel-area rectangle `[west, north, east, south]` in model units, within `tolerance` of one
    /// of the tile's steps `step`.
    pub(super) fn check_placed(
        &self,
        vrt: &Path,
        i: usize,
        area: [f64; 4],
        step: (f64, f64),
        tolerance: f64,
    ) -> Result<()> {
        let s = &self.sources[i];
        let t = &self.transform;
        let placed = [
            t[0] + s.dst[0] * t[1],
            t[3] + s.dst[1] * t[5],
            t[0] + (s.dst[0] + s.dst[2]) * t[1],
            t[3] + (s.dst[1] + s.dst[3]) * t[5],
        ];
        let off = placed
            .iter()
            .zip(area)
            .enumerate()
            .any(|(k, (p, a))| (p - a).abs() > tolerance * if k % 2 == 0 { step.0 } else { step.1 });
        if off {
            return Err(Error::format(
                vrt,
                format!(
                    "GDAL VRT: it puts `{}` at {placed:?} (west, north, east, south), its own \
                     georeference at {area:?}: a VRT that moves, crops or resamples its tiles is not read",
                    s.path.display()
                ),
            ));
        }
        Ok(())
    }

    /// Checks that the VRT's pixels are the mosaic's grid, `fine` (the finest tile's step, x and y),
    /// within `tolerance` of a step: a VRT built at another resolution (`gdalbuildvrt -tr`, or its
    /// default `-resolution average` over tiles of two spacings) is one GDAL reads resampled, so it is
    /// refused with how to build one that is not.
    pub(super) fn check_resolution(
        &self,
        vrt: &Path,
        fine: (f64, f64),
        tolerance: f64,
    ) -> Result<()> {
        let (x, y) = (self.transform[1], -self.transform[5]);
        if (x - fine.0).abs() > tolerance * fine.0 || (y - fine.1).abs() > tolerance * fine.1 {
            return Err(Error::format(
                vrt,
                format!(
                    "GDAL VRT: its pixels are {x} x {y} units, its finest tile's samples {} x {} apart: \
                     GDAL reads it resampled, and a mosaic reads its tiles as they are; build it at \
                     the tiles' own resolution (`gdalbuildvrt -resolution highest`, no `-tr`), or give \
                     the tiles' folder",
                    fine.0, fine.1
                ),
            ));
        }
        Ok(())
    }
}

/// The text of `node`'s first child element named `tag`.
fn child_text<'a>(node: roxmltree::Node<'a, '_>, tag: &str) -> Option<&'a str> {
    node.children().find(|c| c.has_tag_name(tag)).and_then(|c| c.text())
}

/// A `<SrcRect>` or `<DstRect>`: xOff, yOff, xSize, ySize, each finite.
fn rect(node: roxmltree::Node<'_, '_>, tag: &str) -> Option<[f64; 4]> {
    let r = node.children().find(|c| c.has_tag_name(tag))?;
    let mut out = [0.0; 4];
    for (v, name) in out.iter_mut().zip(["xOff", "yOff", "xSize", "ySize"]) {
        *v = r.attribute(name)?.parse().ok().filter(|v: &f64| v.is_finite())?;
    }
    Some(out)
}
