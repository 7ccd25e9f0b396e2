//! Stage 1b, the package: which entropy stage a package's height tiles use ([`CodecKind`]).

use crate::{Error, Param, Result};

/// The entropy stage of a package's height tiles; the prediction is the same for all.
///
/// The SAT LOD record tiles are byte planes under zstd or lz4 ([`super::planes`]); a package whose
/// heights use [`CodecKind::Rans`] codes its records with zstd.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CodecKind {
    /// LZ4 block format (lz4_flex), over zigzag byte planes.
    Lz4,
    /// Zstandard (zstd), over zigzag byte planes.
    Zstd,
    /// Static rANS with context-selected tables (`docs/package-codec.md`), the default.
    Rans,
}

impl CodecKind {
    /// Every codec, for comparisons.
    pub const ALL: [CodecKind; 3] = [CodecKind::Lz4, CodecKind::Zstd, CodecKind::Rans];

    /// The header's code.
    pub fn code(self) -> u32 {
        match self {
            CodecKind::Lz4 => 1,
            CodecKind::Zstd => 2,
            CodecKind::Rans => 3,
        }
    }

    /// The codec of a header code.
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.code() == code)
    }

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            CodecKind::Lz4 => "lz4",
            CodecKind::Zstd => "zstd",
            CodecKind::Rans => "rans",
        }
    }

    /// Parses a name ([`CodecKind::name`]).
    pub fn parse(text: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|c| c.name() == text)
            .ok_or_else(|| Error::param(Param::Codec, format!("`{text}` is not rans, zstd or lz4")))
    }

    /// The byte-plane codec of the SAT LOD record tiles (and of the heights, for lz4 and zstd).
    pub fn planes(self) -> Self {
        match self {
            CodecKind::Rans => CodecKind::Zstd,
            c => c,
        }
    }
}
