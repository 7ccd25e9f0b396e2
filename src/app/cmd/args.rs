//! Application (CLI): the typed option values and the option groups the subcommands share. clap parses and
//! refuses bad values itself (its error names the flag and lists what it accepts); the library's types are
//! mirrored here so that the library holds no CLI words.

use std::fmt;
use std::str::FromStr;

use clap::{Args, ValueEnum};
use clipsat::gpu::GpuMode;
use clipsat::plan::lod::LodMode;
use clipsat::shading::debug_view::DebugView;
use clipsat::shading::Patches;
use clipsat::{Error, Param};

/// `--gpu`: which graphics context renders.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub(crate) enum GpuArg {
    /// Strict if it works, else gl.
    #[default]
    Auto,
    /// A real OpenGL ES 3.0 context (EGL, Mesa's version pinned to 3.0).
    Strict,
    /// wgpu's own GL backend.
    Gl,
    /// wgpu's Vulkan backend on the same GLES 3.0 limits (a build with the `vulkan` feature).
    Vulkan,
}

impl From<GpuArg> for GpuMode {
    fn from(g: GpuArg) -> Self {
        match g {
            GpuArg::Auto => GpuMode::Auto,
            GpuArg::Strict => GpuMode::Strict,
            GpuArg::Gl => GpuMode::Gl,
            GpuArg::Vulkan => GpuMode::Vulkan,
        }
    }
}

/// The `--gpu` option, shared by every command that renders.
#[derive(Args, Clone, Copy, Debug)]
pub(crate) struct GpuArgs {
    /// Graphics context (auto honours $CLIPSAT_GPU: strict, gl or vulkan).
    #[arg(long, value_enum, default_value_t = GpuArg::Auto)]
    pub(crate) gpu: GpuArg,
}

impl GpuArgs {
    /// The library's mode.
    pub(crate) fn mode(&self) -> GpuMode {
        self.gpu.into()
    }
}

/// `--lod`: how block levels are selected.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub(crate) enum LodArg {
    /// Each ring at its own level.
    #[default]
    Distance,
    /// The SAT paper's SFAMF estimate of the block error.
    Sat,
    /// The SAT estimate, never below the true max.
    SatConservative,
    /// The true max over the block (max pyramid).
    Exact,
}

impl From<LodArg> for LodMode {
    fn from(l: LodArg) -> Self {
        match l {
            LodArg::Distance => LodMode::Distance,
            LodArg::Sat => LodMode::Sat,
            LodArg::SatConservative => LodMode::SatConservative,
            LodArg::Exact => LodMode::Exact,
        }
    }
}

/// The LOD options (`--lod`, `--epsilon`), shared by `render`, `fly` and `view`.
#[derive(Args, Clone, Copy, Debug)]
pub(crate) struct LodArgs {
    /// Block level selection (clipmap only; `fly` hashes the SAT modes' selection into the frame hash; in
    /// `view` the initial mode, key L cycles).
    #[arg(long, value_enum, value_name = "MODE", default_value_t = LodArg::Distance)]
    pub(crate) lod: LodArg,
    /// SAT LOD screen-space error bound, pixels (in `view` the initial one, keys [ and ]). Default: the
    /// profile's view.epsilon_px.
    #[arg(long, value_name = "PX", value_parser = positive_px)]
    pub(crate) epsilon: Option<f32>,
}

impl LodArgs {
    /// The library's mode.
    pub(crate) fn mode(&self) -> LodMode {
        self.lod.into()
    }
}

/// Parses a positive, finite number of pixels.
fn positive_px(text: &str) -> Result<f32, String> {
    text.trim()
        .parse::<f32>()
        .ok()
        .filter(|e| e.is_finite() && *e > 0.0)
        .ok_or_else(|| format!("`{text}` is not a positive number of pixels"))
}

/// Streamed or resident terrain (`--resident`, and the old `--stream`), shared by `render`, `fly` and
/// `view`. Streaming is the default: a package streams through the profile's tile cache, and a plain source
/// (PNG, GeoTIFF, .hgt, raw, procedural) is baked into the cache folder on first use (`CLIPSAT_CACHE`, default
/// target/clipsat-cache; a progress bar on stderr) and then streamed the same way.
#[derive(Args, Clone, Copy, Debug, Default)]
pub(crate) struct StreamArgs {
    /// Load the whole terrain instead of streaming it (a package is decoded whole): for what needs every
    /// sample. `render --json` measures the screen error only with it; `render --brute`, `--ground-truth`,
    /// `--oracle` and `--reference` (render, fly) select it by themselves.
    #[arg(long, conflicts_with = "stream")]
    pub(crate) resident: bool,
    /// Stream the terrain: now the default, accepted for old scripts. Refused with the flags that need the
    /// whole terrain (see --resident).
    #[arg(long, hide_short_help = true)]
    pub(crate) stream: bool,
}

impl StreamArgs {
    /// Whether to stream, given `needs_all`, the flags that read every sample (`--brute`, ...), if any:
    /// those select the resident path by themselves, and an explicit `--stream` with them is refused.
    pub(crate) fn streams(&self, needs_all: Option<&str>) -> Result<bool, Error> {
        match needs_all {
            Some(flags) if self.stream => Err(arg_error(
                "--stream",
                format!("needs the whole terrain with {flags}"),
            )),
            Some(_) => Ok(false),
            None => Ok(!self.resident),
        }
    }
}

/// `--debug`: the debug view.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub(crate) enum DebugArg {
    /// The shaded terrain.
    #[default]
    #[value(alias = "none")]
    Normal,
    /// Blocks coloured by their drawn level (the SAT paper's figure 3).
    Levels,
    /// The lattice lines in the level colours.
    Wireframe,
}

impl From<DebugArg> for DebugView {
    fn from(d: DebugArg) -> Self {
        match d {
            DebugArg::Normal => DebugView::Normal,
            DebugArg::Levels => DebugView::Levels,
            DebugArg::Wireframe => DebugView::Wireframe,
        }
    }
}

/// `--shading`: the shading variant.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub(crate) enum ShadingArg {
    /// Height ramp + Lambert.
    #[default]
    Basic,
    /// Reduced spherical Gaussians.
    Sg,
}

/// `--patches`: SG patches per lobe, MxN.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub(crate) enum PatchesArg {
    /// The cheapest.
    #[value(name = "2x4")]
    P2x4,
    /// The SAT paper's choice.
    #[default]
    #[value(name = "4x8")]
    P4x8,
    /// The accurate one.
    #[value(name = "8x16")]
    P8x16,
}

impl From<PatchesArg> for Patches {
    fn from(p: PatchesArg) -> Self {
        match p {
            PatchesArg::P2x4 => Patches::P2x4,
            PatchesArg::P4x8 => Patches::P4x8,
            PatchesArg::P8x16 => Patches::P8x16,
        }
    }
}

/// A size, `WxH` (`x` or `X`), each side a positive whole number. The one WxH parser of the binary.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Size {
    pub(crate) width: u32,
    pub(crate) height: u32,
}

impl Size {
    /// As a (width, height) pair.
    pub(crate) fn pair(self) -> (u32, u32) {
        (self.width, self.height)
    }
}

impl FromStr for Size {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let (w, h) = text
            .split_once(['x', 'X'])
            .ok_or_else(|| format!("`{text}` is not WxH"))?;
        let side = |s: &str, what: &str| {
            s.trim()
                .parse::<u32>()
                .ok()
                .filter(|&v| v > 0)
                .ok_or_else(|| format!("{what} `{s}` is not a positive whole number"))
        };
        Ok(Size {
            width: side(w, "width")?,
            height: side(h, "height")?,
        })
    }
}

impl fmt::Display for Size {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}", self.width, self.height)
    }
}

/// The largest render target side on the GLES 3.0 floor (`Limits::downlevel_webgl2_defaults`).
pub(crate) const MAX_SIDE: u32 = 2048;

/// clap's parser for image sizes: a [`Size`] with each side at most [`MAX_SIDE`].
pub(crate) fn pixel_size(text: &str) -> Result<Size, String> {
    let size: Size = text.parse()?;
    if size.width > MAX_SIDE || size.height > MAX_SIDE {
        return Err(format!(
            "`{text}`: each side at most {MAX_SIDE} pixels (the GLES 3.0 floor)"
        ));
    }
    Ok(size)
}

/// An error about a command-line argument, printed as "argument `--frames`: reason". The library has no
/// such variant (it keeps no CLI words): [`Error::Invalid`] carries the flag.
pub(crate) fn arg_error(flag: &str, reason: impl Into<String>) -> Error {
    Error::Invalid {
        what: format!("argument `{flag}`"),
        reason: reason.into(),
    }
}

/// Names the flag in a library argument error: the library says what was wrong ("flight path"), the binary
/// says which flag carried it.
pub(crate) fn flag(name: &'static str) -> impl Fn(Error) -> Error {
    move |e| match e {
        Error::Invalid { reason, .. } | Error::Param { reason, .. } => arg_error(name, reason),
        other => other,
    }
}

/// The flag (quoted) that sets each library [`Param`]; `None` for one the binary does not expose.
pub(crate) fn flag_of(param: Param) -> Option<&'static str> {
    Some(match param {
        Param::MaxError => "`--max-error`",
        Param::Tile => "`--tile`",
        Param::Codec => "`--codec`",
        Param::SynthLevels => "`--synth-levels`",
        Param::Spacing => "`--spacing M`",
        Param::RawLayout => "`--raw-size WxH` (and `--raw-format u16|f32`)",
        Param::PngEncoding => "`--png-encoding`",
        Param::MaxSamples => "`--max-samples`",
        Param::Nodata => "`--nodata V`",
        Param::ImageryExtent => "`--imagery-extent W,S,E,N`",
        Param::MaxImageryTexels => "`--max-imagery-texels`",
        Param::ImageryRange => "`--imagery-range LO,HI`",
        _ => return None,
    })
}

/// An error as the command line prints it: the library names its options ([`Param`], `Struct::field`), the
/// user sees the flags that set them.
pub(crate) fn cli_message(e: &Error) -> String {
    let mut text = match e {
        Error::Param { param, reason } => format!("argument `{param}`: {reason}"),
        other => other.to_string(),
    };
    for param in Param::ALL {
        if let Some(words) = flag_of(param) {
            text = text.replace(&format!("`{param}`"), words);
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_param_has_a_flag() {
        for param in Param::ALL {
            assert!(flag_of(param).is_some(), "{param} has no flag");
        }
        let e = Error::param(Param::MaxError, "0 m must be finite and positive");
        assert_eq!(
            cli_message(&e),
            "argument `--max-error`: 0 m must be finite and positive"
        );
        let e = Error::format("a.raw", format!("give `{}`", Param::RawLayout));
        assert!(
            cli_message(&e).contains("`--raw-size WxH`"),
            "{}",
            cli_message(&e)
        );
    }

    #[test]
    fn sizes_parse_and_refuse() {
        assert_eq!(
            "640x360".parse::<Size>(),
            Ok(Size {
                width: 640,
                height: 360
            })
        );
        assert_eq!("2X3".parse::<Size>().map(Size::pair), Ok((2, 3)));
        for bad in ["640", "0x5", "ax5", "5x", "-1x4"] {
            assert!(bad.parse::<Size>().is_err(), "{bad}");
        }
        assert!(pixel_size("2049x10").is_err());
        assert!(pixel_size("2048x2048").is_ok());
    }

    #[test]
    fn value_enums_name_the_library_modes() {
        for (arg, mode) in LodArg::value_variants().iter().zip(LodMode::ALL) {
            assert_eq!(LodMode::from(*arg), mode);
            assert_eq!(
                arg.to_possible_value().map(|v| v.get_name().to_string()),
                Some(mode.to_string())
            );
        }
        for (arg, p) in PatchesArg::value_variants().iter().zip(Patches::ALL) {
            assert_eq!(Patches::from(*arg), p);
            assert_eq!(
                arg.to_possible_value().map(|v| v.get_name().to_string()),
                Some(p.label().to_string())
            );
        }
    }
}
