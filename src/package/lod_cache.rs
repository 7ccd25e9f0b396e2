//! Stage 1b, the package: SAT LOD's tables of a streamed package, through the LOD tables' disk cache
//! ([`crate::bake`]'s, keyed here by the package header): read through the cache file's map, or baked
//! on a miss from the package's own records ([`super::lod_bake`]) or out of core from its heights
//! ([`super::lod_stream`]).

use std::path::Path;

use crate::bake::lod_tables::LodTables;
use crate::bake::sat::Sat;
use crate::bake::{
    bake_uncached, cache_path, read_cached, remove_last_format, BakeParams, CacheOutcome, FORMAT_VERSION,
};
use crate::hash::Hash64;
use crate::progress::Progress;
use crate::{Error, Result};

use super::{lod_bake, lod_stream};

/// The cache key of a package's tables: its header (dimensions, spacing, quantum, and every tile's
/// offset and CRC-32, so any change to its heights) and the parameters.
pub fn package_cache_key(package: &super::Package, params: &BakeParams) -> u64 {
    key_of_version(package, params, FORMAT_VERSION)
}

/// [`package_cache_key`] as format `version` made it.
fn key_of_version(package: &super::Package, params: &BakeParams, version: u32) -> u64 {
    let mut h = Hash64::new();
    h.write_u32(version);
    h.write_bytes(b"package");
    h.write_bytes(&package.header().to_bytes());
    h.write_u32(params.p);
    let h0 = package.header();
    h.write_u32(Sat::max_frac_bits(
        u64::from(h0.width) * u64::from(h0.height),
    ));
    h.write_u32(params.levels);
    h.write_u32(params.synth_levels);
    h.write_u64(params.g0.to_bits());
    h.finish()
}

/// The LOD tables of a streamed package, read through the cache file's map. On a miss they are baked out
/// of core ([`lod_stream`]: the package read a band of tiles at a time, the file written row by row, the
/// same bytes as a bake from the decoded pyramid), then mapped; a hit decodes nothing and copies no table
/// into memory. When the cache file cannot be written, the tables are baked in memory from the decoded
/// package instead (outcome [`CacheOutcome::NotCached`]).
pub fn bake_lod_package(
    package: &super::Package,
    params: &BakeParams,
    dir: &Path,
    progress: Progress<'_>,
) -> Result<(LodTables, CacheOutcome)> {
    let (lo, hi) = package.header().range;
    if !(hi - lo).is_finite() {
        return Err(Error::terrain(format!(
            "heights span {lo:e} .. {hi:e} m, a range too large for f32 arithmetic (it overflows); \
             scale them down, or use distance LOD"
        )));
    }
    let key = package_cache_key(package, params);
    let path = cache_path(dir, key);
    let refused = match read_cached(&path, key, params) {
        Some(Ok(t)) => return Ok((t, CacheOutcome::Hit)),
        Some(Err(reason)) => Some(reason),
        None => None,
    };
    // A miss: first the temporaries a killed bake left in the cache folder (`crate::temp`).
    crate::temp::sweep(dir);
    // The package's own records when they cover the profile (no error computed), else the heights.
    let baked = if lod_bake::records_cover(package, params) {
        lod_bake::tables_from_records(package, params, key, &path)
    } else {
        lod_stream::bake_to_file(package, params, key, &path, progress)
    };
    match baked {
        Ok(()) => {}
        // The cache file could not be written (not the package read): bake in memory.
        Err(e @ Error::Io { .. }) if !matches!(&e, Error::Io { path: p, .. } if p == package.path()) =>
        {
            let pyramid = package.to_pyramid()?;
            crate::bake::lod_tables::check_height_range(&pyramid)?;
            let tables = bake_uncached(&pyramid, params, progress)?;
            return Ok((tables, CacheOutcome::NotCached(e.to_string())));
        }
        Err(e) => return Err(e),
    }
    let tables = match read_cached(&path, key, params) {
        Some(Ok(t)) => t,
        Some(Err(reason)) => return Err(Error::format(&path, reason)),
        None => return Err(Error::format(&path, "the LOD tables just written are gone")),
    };
    remove_last_format(dir, |v| key_of_version(package, params, v));
    let outcome = match refused {
        Some(r) => CacheOutcome::Rebaked(r),
        None => CacheOutcome::Baked,
    };
    Ok((tables, outcome))
}

