//! Stage 3 input, built once at start-up: the static block meshes the clipmap renderer draws (pure CPU).
//!
//! GPU Gems 2 ch. 2 draws each ring from m x m blocks (m = (n + 1) / 4), fix-ups, L-shaped trims and
//! stitches. This renderer uses a simpler tiling that stays correct when the budget crops an active region
//! to any even-aligned rectangle (GC section 5): the render region, active(l) minus active(l - 1), is split
//! into at most four rectangles, each tiled by one B x B-quad block mesh (B = m) whose vertices the vertex
//! shader clamps into the rectangle. Clamped vertices collapse the block's surplus quads into zero-area
//! triangles, so coverage is exactly the rectangle whatever its size: no fix-up or trim meshes are needed,
//! and a full ring (bands m - 1 and m quads thick) takes 12 blocks, as in GPU Gems 2.
//!
//! Level boundaries are closed by skirts (flanges, as in the SAT paper) rather than GC section 6.2's
//! zero-area stitches, because cropped (stale) levels can leave the outer morph weight below 1 and the
//! SAT-LOD issue will draw neighbouring blocks at different levels: one ring-shaped skirt mesh, a loop of
//! vertical quads around a (n + 1)-quad square, clamped onto any rectangle's boundary the same way.
//!
//! Meshes are in lattice units, so one block and one skirt mesh serve every level (the level's spacing and
//! origin are per-draw uniforms); that is all "the precomputed per-level vertex buffers" need to hold.

/// One mesh vertex: lattice x (east), lattice y (south), skirt flag (1 = the skirt's lower edge), unused.
///
/// Mirrors the `@location(0) vec4<u32>` (Uint16x4) vertex attribute of `shaders_gles/clipmap.wgsl`.
pub type MeshVertex = [u16; 4];

/// A static mesh: vertices and a u16 triangle list.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Mesh {
    /// Vertices.
    pub vertices: Vec<MeshVertex>,
    /// Triangle list indices into `vertices`.
    pub indices: Vec<u16>,
}

impl Mesh {
    /// Triangles the mesh draws (degenerate ones included).
    pub fn triangles(&self) -> u32 {
        u32::try_from(self.indices.len() / 3).expect("u16-indexed mesh")
    }

    /// Bytes of its vertex and index buffers on the GPU.
    pub fn bytes(&self) -> u64 {
        (self.vertices.len() * std::mem::size_of::<MeshVertex>() + self.indices.len() * 2) as u64
    }
}

/// Bytes of [`block`]`(quads)`'s buffers, without building it (for the profile's footprint); saturates
/// rather than wraps for sizes no valid profile has.
pub fn block_bytes(quads: u32) -> u64 {
    let q = u64::from(quads);
    ((q + 1) * (q + 1))
        .saturating_mul(8)
        .saturating_add((q * q).saturating_mul(12))
}

/// Bytes of [`skirt`]`(side)`'s buffers, without building it.
pub fn skirt_bytes(side: u32) -> u64 {
    let s = u64::from(side);
    2 * (4 * s + 1) * 8 + 4 * s * 6 * 2
}

/// A `quads x quads` grid of vertices (0..=quads)^2, two triangles per quad, in shell order: indices
/// `0..6 k^2` are the top-left k x k quads ([`block_prefix`]).
///
/// Quads split along (i, j)-(i+1, j+1), the project-wide diagonal (the one `clipmap`'s odd-odd z_c and the
/// brute-force reference use), so the clipmap surface is the same piecewise-linear surface.
pub fn block(quads: u32) -> Mesh {
    let side = quads + 1;
    assert!(
        side * side <= 1 << 16,
        "block of {quads} quads exceeds u16 indices"
    );
    let q = u16::try_from(quads).expect("checked above");
    let mut vertices = Vec::with_capacity(side as usize * side as usize);
    for y in 0..=q {
        for x in 0..=q {
            vertices.push([x, y, 0, 0]);
        }
    }
    let mut indices = Vec::with_capacity(quads as usize * quads as usize * 6);
    let s = q + 1;
    let mut quad = |x: u16, y: u16| {
        let nw = y * s + x;
        let (ne, sw) = (nw + 1, nw + s);
        let se = sw + 1;
        indices.extend_from_slice(&[nw, sw, se, nw, se, ne]);
    };
    // Shell order (quads with max(x, y) = k after every quad of a smaller k): the first k^2 quads are the
    // k x k top-left square, so a block of fewer quads (SAT LOD) draws a prefix of the index buffer.
    for k in 0..q {
        for y in 0..k {
            quad(k, y);
        }
        for x in 0..=k {
            quad(x, k);
        }
    }
    Mesh { vertices, indices }
}

/// Indices of [`block`]'s top-left `k x k` quads (a prefix of its index buffer).
pub fn block_prefix(k: u32) -> u32 {
    6 * k * k
}

/// The tile skirt loops: closed skirts ([`skirt`]) of sides 1, 2, 4, ..., `max_side` (a power of two) in one
/// mesh, so a tile of k quads hangs the smallest loop of side >= k ([`skirt_loop_range`]) rather than one of
/// `max_side`.
pub fn skirt_loops(max_side: u32) -> Mesh {
    assert!(
        max_side.is_power_of_two(),
        "skirt loops up to a power of two"
    );
    let mut out = Mesh::default();
    let mut side = 1;
    while side <= max_side {
        let base = u16::try_from(out.vertices.len()).expect("skirt loops exceed u16 indices");
        let l = skirt(side);
        out.vertices.extend_from_slice(&l.vertices);
        out.indices.extend(
            l.indices
                .iter()
                .map(|&i| i.checked_add(base).expect("skirt loops exceed u16 indices")),
        );
        side *= 2;
    }
    out
}

/// Bytes of [`skirt_loops`]`(max_side)`'s buffers, without building it.
pub fn skirt_loops_bytes(max_side: u32) -> u64 {
    // u64 sides: doubling past 2^31 must end the loop, not wrap.
    let mut side = 1u64;
    let mut bytes = 0u64;
    while side <= u64::from(max_side) {
        bytes = bytes.saturating_add(skirt_bytes(u32::try_from(side).unwrap_or(u32::MAX)));
        side *= 2;
    }
    bytes
}

/// The index range of the smallest loop of [`skirt_loops`]`(max_side)` whose side is at least `quads`
/// (capped at `max_side`).
pub fn skirt_loop_range(max_side: u32, quads: u32) -> std::ops::Range<u32> {
    let side = quads.max(1).next_power_of_two().min(max_side);
    // Loop of side s has 4 s segments of 6 indices; the loops before it sum to 24 (side - 1).
    let first = 24 * (side - 1);
    first..first + 24 * side
}

/// The detail pool's cell mesh: [`block`]`(quads)`'s vertices, then [`skirt_loops`]`(quads)`'s,
/// and for each k in 1..=quads one run of indices: the block's top-left k x k quads, then the smallest
/// loop of side >= k. So a pool cell and its skirt are one draw ([`pool_cell_range`]), drawn in the order
/// its two draws had (surface, then skirt): a cell per draw is what lets the pool hold more tiles than
/// half the draw budget.
pub fn pool_cells(quads: u32) -> Mesh {
    let b = block(quads);
    let l = skirt_loops(quads);
    assert!(
        b.vertices.len() + l.vertices.len() <= 1 << 16,
        "pool cells of {quads} quads exceed u16 indices"
    );
    let base = u16::try_from(b.vertices.len()).expect("checked above");
    let mut vertices = b.vertices;
    vertices.extend_from_slice(&l.vertices);
    let mut indices = Vec::with_capacity(pool_cells_indices(quads) as usize);
    for k in 1..=quads {
        indices.extend_from_slice(&b.indices[..block_prefix(k) as usize]);
        let r = skirt_loop_range(quads, k);
        indices.extend(
            l.indices[r.start as usize..r.end as usize]
                .iter()
                .map(|&i| i + base),
        );
    }
    if quads >= 2 {
        // A stitched cell's units (`crate::plan::detail::stitch`): the fan is the block's top-left 2 x 2
        // quads; the coarse quad joins its corners along the same diagonal.
        indices.extend_from_slice(&b.indices[..block_prefix(2) as usize]);
        let q = u16::try_from(quads + 1).expect("checked above");
        let (nw, ne, sw) = (0, 2, 2 * q);
        indices.extend_from_slice(&[nw, sw, sw + 2, nw, sw + 2, ne]);
        // Skirt sides from the loop of side 2 (after the loop of side 1's 10 vertices and 24 indices):
        // side s's two segments, then its one segment corner to corner.
        let vb = base + 10;
        for s in 0..4u16 {
            let r = 24 + 12 * usize::from(s);
            indices.extend(l.indices[r..r + 12].iter().map(|&i| i + base));
            let (t0, t1) = (vb + 4 * s, vb + 4 * s + 4);
            indices.extend_from_slice(&[t0, t0 + 1, t1 + 1, t0, t1 + 1, t1]);
        }
    }
    Mesh { vertices, indices }
}

/// One mesh of a stitched cell's unit ([`crate::plan::detail::stitch`]), in the lattice of the
/// cell's level from the unit's first vertex: a unit is one quad of the next coarser level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum UnitMesh {
    /// The unit's four quads of the cell's level (8 triangles around its centre).
    Fan,
    /// The one coarser quad, corner to corner (2 triangles).
    Coarse,
    /// The skirt under side `side` (0: -y, 1: +x, 2: +y, 3: -x, the skirt loop's order): two segments,
    /// or one corner to corner when `coarse`.
    Skirt {
        /// Which side.
        side: u8,
        /// The unit is coarse.
        coarse: bool,
    },
}

/// Indices of [`pool_cells`]`(quads)`: its runs for every k, then (from 2 quads on) the unit meshes.
fn pool_cells_indices(quads: u32) -> u32 {
    let runs = pool_cell_range(quads, quads).end;
    if quads >= 2 {
        runs + 24 + 6 + 4 * (12 + 6)
    } else {
        runs
    }
}

/// The index range of [`pool_cells`]`(quads)` (`quads` >= 2) that draws unit mesh `unit`.
pub fn pool_unit_range(quads: u32, unit: UnitMesh) -> std::ops::Range<u32> {
    assert!(quads >= 2, "stitched units need cells of 2 quads or more");
    let first = pool_cell_range(quads, quads).end;
    match unit {
        UnitMesh::Fan => first..first + 24,
        UnitMesh::Coarse => first + 24..first + 30,
        UnitMesh::Skirt { side, coarse } => {
            let s = first + 30 + 18 * u32::from(side.min(3));
            if coarse {
                s + 12..s + 18
            } else {
                s..s + 12
            }
        }
    }
}

/// Indices of [`pool_cells`]`(quads)`'s run for a cell of `k` quads (1..=quads).
fn pool_run(quads: u32, k: u32) -> u32 {
    let r = skirt_loop_range(quads, k);
    block_prefix(k) + (r.end - r.start)
}

/// The index range of [`pool_cells`]`(quads)` that draws a cell of `k` quads (clamped to 1..=quads) and
/// its skirt: as many triangles as [`block_prefix`]`(k)` and [`skirt_loop_range`]`(quads, k)` together.
pub fn pool_cell_range(quads: u32, k: u32) -> std::ops::Range<u32> {
    let k = k.clamp(1, quads.max(1));
    let start: u32 = (1..k).map(|j| pool_run(quads, j)).sum();
    start..start + pool_run(quads, k)
}

/// Bytes of [`pool_cells`]`(quads)`'s buffers, without building it.
pub fn pool_cells_bytes(quads: u32) -> u64 {
    let q = u64::from(quads);
    let mut loop_vertices = 0u64;
    let mut side = 1u64;
    while side <= q {
        loop_vertices += 2 * (4 * side + 1);
        side *= 2;
    }
    ((q + 1) * (q + 1) + loop_vertices) * 8 + u64::from(pool_cells_indices(quads)) * 2
}

/// A closed skirt around the square [0, side]^2: for each of the 4 side + 1 boundary points (walked
/// clockwise on screen: north edge east-bound, east edge south-bound, ...), an upper vertex (flag 0) and a
/// lower one (flag 1), joined by two triangles per boundary segment.
pub fn skirt(side: u32) -> Mesh {
    let points = 4 * side + 1;
    assert!(
        2 * points <= 1 << 16,
        "skirt of side {side} exceeds u16 indices"
    );
    let s = u16::try_from(side).expect("checked above");
    let mut vertices = Vec::with_capacity(2 * points as usize);
    for k in 0..points {
        let k = u16::try_from(k).expect("checked above");
        let (x, y) = match k / s.max(1) {
            0 => (k, 0),
            1 => (s, k - s),
            2 => (3 * s - k, s),
            _ => (0, (4 * s).saturating_sub(k)),
        };
        vertices.push([x, y, 0, 0]);
        vertices.push([x, y, 1, 0]);
    }
    let mut indices = Vec::with_capacity(4 * side as usize * 6);
    for k in 0..4 * s {
        let (t0, b0, t1, b1) = (2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3);
        indices.extend_from_slice(&[t0, b0, b1, t0, b1, t1]);
    }
    Mesh { vertices, indices }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pool_cells_are_a_block_prefix_then_its_loop() {
        let (b, l, p) = (block(8), skirt_loops(8), pool_cells(8));
        assert_eq!(p.bytes(), pool_cells_bytes(8));
        assert_eq!(p.indices.len(), pool_cells_indices(8) as usize);
        let base = b.vertices.len();
        for k in 1..=8u32 {
            let r = pool_cell_range(8, k);
            let run = &p.indices[r.start as usize..r.end as usize];
            let n = block_prefix(k) as usize;
            let lr = skirt_loop_range(8, k);
            assert_eq!(run.len(), n + (lr.end - lr.start) as usize, "k {k}");
            assert_eq!(&run[..n], &b.indices[..n]);
            for (&i, &j) in run[n..]
                .iter()
                .zip(&l.indices[lr.start as usize..lr.end as usize])
            {
                assert_eq!(p.vertices[usize::from(i)], l.vertices[usize::from(j)]);
                assert!(usize::from(i) >= base);
            }
        }
    }

    #[test]
    fn block_is_a_grid_with_the_project_diagonal() {
        let b = block(4);
        assert_eq!(b.vertices.len(), 25);
        assert_eq!(b.triangles(), 32);
        assert_eq!(&b.indices[..6], &[0, 5, 6, 0, 6, 1]);
        assert_eq!(b.bytes(), block_bytes(4));
        assert!(b.indices.iter().all(|&i| usize::from(i) < b.vertices.len()));
        // Every prefix of k^2 quads is exactly the k x k top-left square.
        for k in 0..=4u16 {
            let n = block_prefix(u32::from(k)) as usize;
            let mut seen: Vec<u16> = b.indices[..n].to_vec();
            seen.sort_unstable();
            seen.dedup();
            assert!(seen.iter().all(|&i| i % 5 <= k && i / 5 <= k), "k {k}");
            assert_eq!(
                seen.len(),
                if k == 0 { 0 } else { usize::from(k + 1).pow(2) }
            );
        }
    }

    #[test]
    fn skirt_loops_hold_every_power_of_two() {
        let m = skirt_loops(8);
        assert_eq!(m.bytes(), skirt_loops_bytes(8));
        assert_eq!(m.indices.len(), skirt_loop_range(8, 8).end as usize);
        for (q, side) in [(0, 1), (1, 1), (2, 2), (3, 4), (5, 8), (8, 8), (20, 8)] {
            let r = skirt_loop_range(8, q);
            let ix = &m.indices[r.start as usize..r.end as usize];
            // The loop's upper vertices span exactly [0, side] in x and y.
            let xs: Vec<u16> = ix.iter().map(|&i| m.vertices[usize::from(i)][0]).collect();
            assert_eq!(xs.iter().max(), Some(&side), "q {q}");
            assert_eq!(ix.len(), 24 * usize::from(side));
        }
    }

    #[test]
    fn skirt_walks_the_square_boundary() {
        let s = skirt(4);
        assert_eq!(s.vertices.len(), 2 * 17);
        assert_eq!(s.bytes(), skirt_bytes(4));
        // Every upper vertex is on the boundary; consecutive points are one lattice step apart; closed.
        let tops: Vec<[u16; 4]> = s.vertices.iter().step_by(2).copied().collect();
        for w in tops.windows(2) {
            let d = (i32::from(w[0][0]) - i32::from(w[1][0])).abs()
                + (i32::from(w[0][1]) - i32::from(w[1][1])).abs();
            assert_eq!(d, 1, "{w:?}");
        }
        assert_eq!(tops[0], tops[16]);
        assert!(tops
            .iter()
            .all(|v| v[0] == 0 || v[0] == 4 || v[1] == 0 || v[1] == 4));
        assert!(s.vertices.iter().skip(1).step_by(2).all(|v| v[2] == 1));
    }
}
