//! The embedding API: the budget profile every size is fixed from.

use crate::profile;
use crate::Result;

/// A budget profile: GPU and CPU memory, samples updated, draws and triangles per frame, the clipmap's
/// rings, and the shading features allowed. Everything a [`crate::TerrainRenderer`] allocates is sized
/// from it, once.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile(pub(crate) profile::Profile);

impl Profile {
    /// A shipped profile by name (`gles3-low`, `gles3-mid`, `desktop`), or a TOML file by path; refused
    /// with the field at fault when a value is missing, mistyped or out of range.
    pub fn load(name_or_path: &str) -> Result<Self> {
        profile::Profile::load(name_or_path).map(Self)
    }

    /// A profile from TOML text (the shipped profiles' format); `name` names it in errors.
    pub fn from_toml(name: &str, text: &str) -> Result<Self> {
        profile::Profile::parse(name, text).map(Self)
    }

    /// The profile's name (a shipped name, or the path or name it was read from).
    pub fn name(&self) -> &str {
        &self.0.name
    }
}

#[cfg(feature = "internals")]
impl Profile {
    /// The stages' profile.
    pub fn get(&self) -> &profile::Profile {
        &self.0
    }

    /// The stages' profile as the public one (a shipped profile the binary changed, such as its viewport).
    pub fn from_stages(profile: profile::Profile) -> Self {
        Self(profile)
    }
}
