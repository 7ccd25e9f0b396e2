//! Errors of every stage: one `#[non_exhaustive]` enum, so callers match on what went wrong, not on text.

use std::path::PathBuf;

/// Everything that can go wrong in clipsat. Input problems name the file, field or argument at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be opened, read or written.
    #[error("{}: {action}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done ("cannot read", "cannot write").
        action: &'static str,
        /// The operating-system error.
        #[source]
        source: std::io::Error,
    },
    /// A terrain file is malformed: empty, truncated, wrong magic, or an unsupported layout.
    #[error("{}: {reason}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A terrain declares more samples than the memory limit allows; refused before allocating.
    #[error(
        "{}: declared size {width} x {height} = {samples} samples is over the limit of {limit} samples \
         (raise `{}` if this is intended)",
        path.display(),
        Param::MaxSamples
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Declared width in samples.
        width: u64,
        /// Declared height in samples.
        height: u64,
        /// width * height.
        samples: u64,
        /// The limit in force.
        limit: u64,
    },
    /// A file's length does not match the size its format or the given dimensions imply.
    #[error("{}: file is {actual} bytes, expected {expected}", path.display())]
    SizeMismatch {
        /// The file.
        path: PathBuf,
        /// The file's length in bytes.
        actual: u64,
        /// What was expected, in words ("2884802 bytes (1201 x 1201 int16)").
        expected: String,
    },
    /// A height sample is NaN or infinite.
    #[error(
        "{}: sample at column {x}, row {y} is {value}; heights must be finite{}",
        path.display(),
        nan_hint(path, *value)
    )]
    NonFinite {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// Column.
        x: u32,
        /// Row.
        y: u32,
        /// The offending value.
        value: f32,
    },
    /// A budget profile or scene field is missing, mistyped or out of range.
    #[error("{source_name}: field `{field}`: {reason}")]
    Config {
        /// The profile or scene (shipped name or path).
        source_name: String,
        /// The field at fault, dotted (`clipmap.n`).
        field: String,
        /// Why it is refused.
        reason: String,
    },
    /// A library option is out of range or unusable; names the option as a [`Param`] (the binary maps it
    /// to its flag when it prints).
    #[error("`{param}`: {reason}")]
    Param {
        /// The option at fault.
        param: Param,
        /// Why it is refused.
        reason: String,
    },
    /// A value handed to the library is refused (an option, a plan for another frame, an index); names
    /// what, in the library's words (the binary maps it to its flags).
    #[error("{what}: {reason}")]
    Invalid {
        /// What was refused.
        what: String,
        /// Why.
        reason: String,
    },
    /// The terrain's heights are finite but too extreme for a stage's arithmetic (its f32 values
    /// overflow): refused with the stage and the place, never a panic or a silent infinity.
    #[error("terrain: {reason}")]
    Terrain {
        /// What overflows, and where.
        reason: String,
    },
    /// A camera is unusable (not finite, no look direction, clip planes out of order...).
    #[error("camera: {reason}")]
    Camera {
        /// What is wrong with it.
        reason: String,
    },
    /// A fixed-capacity per-frame collection would overflow: the profile's maximum is too small.
    #[error("capacity exceeded: {what} needs more than {capacity}")]
    Capacity {
        /// The collection.
        what: &'static str,
        /// Its capacity.
        capacity: usize,
    },
    /// No GPU adapter or device could be created.
    #[error("no GPU adapter: {reason}")]
    NoAdapter {
        /// What was tried, and what to do about it.
        reason: String,
        /// The graphics API's error, where there is one.
        #[source]
        source: Option<BoxError>,
    },
    /// The device is below what the profile needs: a limit smaller than the profile asks. Choose a
    /// smaller profile, or a device that offers more.
    #[error("the GPU device offers {available} for `{limit}`; the profile needs {needed}")]
    Unsupported {
        /// The limit, as wgpu names it (`max_texture_array_layers`).
        limit: &'static str,
        /// What the profile needs.
        needed: u64,
        /// What the device offers.
        available: u64,
    },
    /// A frame plan handed to the renderer does not follow the clipmap frame it is for (planned from
    /// an older frame, or for another clipmap): plan the clipmap's latest frame, then prepare.
    #[error(
        "stale plan: {}, the clipmap is at frame {current}",
        planned.map_or("never planned".to_string(), |f| format!("planned for clipmap frame {f}"))
    )]
    StalePlan {
        /// The clipmap frame the plan was made for (None: an empty plan).
        planned: Option<u64>,
        /// The clipmap's latest frame.
        current: u64,
    },
    /// The GPU failed after start-up (device lost, out of memory, validation, a read-back).
    #[error("GPU: {action}")]
    Gpu {
        /// What was being done.
        action: String,
        /// The graphics API's error, where there is one.
        #[source]
        source: Option<BoxError>,
    },
}

/// An error of another library, kept as the [`std::error::Error::source`] of an [`Error`].
pub type BoxError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// An option of the library's API that an error can name, in the library's words (`struct::field`). The
/// library keeps no command-line words: the `clipsat` binary maps each to its flag when it prints.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Param {
    /// The package's quantisation error bound (the bake's `max_error`).
    MaxError,
    /// The package's tile size (the bake's `tile`).
    Tile,
    /// The package's tile codec (the bake's `codec`).
    Codec,
    /// Rings synthesised finer than the data (the clipmap's `synth_levels`).
    SynthLevels,
    /// The sample spacing given for a terrain ([`crate::TerrainOptions::spacing_m`]).
    Spacing,
    /// A headerless raw file's layout (width, height, sample type).
    RawLayout,
    /// How a PNG's pixels hold heights (grey, or a web-map RGB encoding).
    PngEncoding,
    /// The most samples a terrain file may declare.
    MaxSamples,
    /// The value given as marking voids ([`crate::TerrainOptions::nodata`]).
    Nodata,
    /// Where imagery lies on the terrain ([`crate::TerrainOptions::imagery_extent`]).
    ImageryExtent,
    /// The most texels an imagery file may declare.
    MaxImageryTexels,
    /// The imagery's sample values drawn black and white ([`crate::TerrainOptions::imagery_range`]).
    ImageryRange,
}

impl Param {
    /// Every parameter, so a caller that maps them (the binary to its flags) can check it maps all.
    pub const ALL: [Param; 12] = [
        Self::MaxError,
        Self::Tile,
        Self::Codec,
        Self::SynthLevels,
        Self::Spacing,
        Self::RawLayout,
        Self::PngEncoding,
        Self::MaxSamples,
        Self::Nodata,
        Self::ImageryExtent,
        Self::MaxImageryTexels,
        Self::ImageryRange,
    ];

    /// The option's name in the library, `Struct::field`; messages quote it in backticks.
    pub fn name(self) -> &'static str {
        match self {
            Self::MaxError => "BakeOptions::max_error",
            Self::Tile => "BakeOptions::tile",
            Self::Codec => "BakeOptions::codec",
            Self::SynthLevels => "ClipmapOptions::synth_levels",
            Self::Spacing => "TerrainOptions::spacing_m",
            Self::RawLayout => "LoadOptions::raw",
            Self::PngEncoding => "LoadOptions::png_encoding",
            Self::MaxSamples => "TerrainOptions::max_samples",
            Self::Nodata => "TerrainOptions::nodata",
            Self::ImageryExtent => "TerrainOptions::imagery_extent",
            Self::MaxImageryTexels => "TerrainOptions::max_imagery_texels",
            Self::ImageryRange => "TerrainOptions::imagery_range",
        }
    }
}

impl std::fmt::Display for Param {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An [`Error::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, action: &'static str, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            action,
            source,
        }
    }

    /// An [`Error::Format`] for `path`.
    pub fn format(path: impl Into<PathBuf>, reason: impl Into<String>) -> Self {
        Self::Format {
            path: path.into(),
            reason: reason.into(),
        }
    }

    /// An [`Error::Param`] for `param`.
    pub fn param(param: Param, reason: impl Into<String>) -> Self {
        Self::Param {
            param,
            reason: reason.into(),
        }
    }

    /// An [`Error::Gpu`] caused by `source`.
    pub(crate) fn gpu(action: impl Into<String>, source: impl Into<BoxError>) -> Self {
        Self::Gpu {
            action: action.into(),
            source: Some(source.into()),
        }
    }

    /// An [`Error::Gpu`] with no cause beyond its words.
    pub(crate) fn gpu_msg(action: impl Into<String>) -> Self {
        Self::Gpu {
            action: action.into(),
            source: None,
        }
    }

    /// An [`Error::NoAdapter`], caused by `source` when given.
    pub(crate) fn no_adapter(reason: impl Into<String>, source: Option<BoxError>) -> Self {
        Self::NoAdapter {
            reason: reason.into(),
            source,
        }
    }

    /// An [`Error::Camera`].
    pub(crate) fn camera(reason: impl Into<String>) -> Self {
        Self::Camera {
            reason: reason.into(),
        }
    }

    /// An [`Error::Terrain`].
    pub(crate) fn terrain(reason: impl Into<String>) -> Self {
        Self::Terrain {
            reason: reason.into(),
        }
    }

    /// An [`Error::Config`].
    pub fn config(
        source_name: impl Into<String>,
        field: impl Into<String>,
        reason: impl Into<String>,
    ) -> Self {
        Self::Config {
            source_name: source_name.into(),
            field: field.into(),
            reason: reason.into(),
        }
    }
}

/// `e` and each of its sources, joined by ": " (an error nested in another's words).
pub(crate) fn with_sources(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        text.push_str(": ");
        text.push_str(&s.to_string());
        source = s.source();
    }
    text
}

/// What to do about a NaN sample in a format with a nodata value (GeoTIFF, ASCII grid): files mark voids
/// that way, and a declared nodata value of NaN fills them.
fn nan_hint(path: &std::path::Path, value: f32) -> &'static str {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        _ if !value.is_nan() => "",
        Some("tif" | "tiff") => {
            " (if NaN marks voids, give NaN as `TerrainOptions::nodata`, or declare NaN the file's nodata value \
             as GDAL's `gdal_edit.py -a_nodata nan FILE` does, and they are filled from their neighbours)"
        }
        Some("asc") => {
            " (if NaN marks voids, give NaN as `TerrainOptions::nodata`, or write `NODATA_value nan` in the \
             header, and they are filled from their neighbours)"
        }
        Some("png") => "",
        _ => {
            " (if NaN marks voids, give NaN as `TerrainOptions::nodata`, and they are filled from their \
             neighbours)"
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The library keeps no command-line words: no string in `src/` outside the binary's `src/app` names a
    /// flag (`"--x"` or `--x` inside a literal). Errors name a [`Param`]; the binary maps it to its flag.
    #[test]
    fn library_names_no_flags() {
        let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut stack = vec![src.clone()];
        let mut hits = Vec::new();
        let mut files = 0;
        while let Some(dir) = stack.pop() {
            let entries =
                std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
            for entry in entries.flatten() {
                let path = entry.path();
                if path == src.join("app") || path == src.join("main.rs") {
                    continue;
                }
                if path.is_dir() {
                    stack.push(path);
                } else if path.extension().is_some_and(|e| e == "rs") {
                    files += 1;
                    let text = std::fs::read_to_string(&path)
                        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                    for (i, line) in text.lines().enumerate() {
                        if flag_in_code(line) {
                            hits.push(format!("{}:{}: {}", path.display(), i + 1, line.trim()));
                        }
                    }
                }
            }
        }
        assert!(
            files > 20,
            "scanned only {files} files under {}",
            src.display()
        );
        assert!(
            hits.is_empty(),
            "library code names CLI flags:\n{}",
            hits.join("\n")
        );
    }

    /// Two dashes, spelled so that this file does not match its own scan.
    const DASHES: &str = concat!("-", "-");

    /// Whether the code part of `line` (before a `//` comment) holds `"--` or `--` before a letter.
    fn flag_in_code(line: &str) -> bool {
        let code = line.split("//").next().unwrap_or(line);
        code.contains(&format!("\"{DASHES}"))
            || code
                .match_indices(DASHES)
                .any(|(i, _)| code[i + 2..].starts_with(|c: char| c.is_ascii_lowercase()))
    }

    #[test]
    fn flag_scan_sees_flags() {
        assert!(flag_in_code(&format!(
            "    arg: \"{DASHES}max-error\".into(),"
        )));
        assert!(flag_in_code(&format!(
            "    \"give one with {DASHES}spacing M\","
        )));
        assert!(!flag_in_code("    // the `--spacing` flag"));
        assert!(!flag_in_code("    let x = a - -b; // ----"));
        let names: std::collections::HashSet<_> = Param::ALL.iter().map(|p| p.name()).collect();
        assert_eq!(names.len(), Param::ALL.len(), "parameter names are unique");
    }
}
