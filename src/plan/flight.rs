//! Per-frame plan, its input: camera paths over a terrain, pure functions of the frame index (no clock).
//!
//! A [`Flight`] turns a frame index into a [`Camera`]. Cruising paths follow a horizontal track at a height
//! taken from a smoothed upper envelope of the terrain, so the eye neither jitters with every bump nor
//! ever dips under the ground; every eye is also clamped to at least [`Flight::min_clearance`] above the
//! exact terrain height under it. Speed is metres per frame along the track (along the slope for `dive`).

use std::f64::consts::TAU;
use std::fmt;
use std::str::FromStr;

use glam::{DVec2, DVec3};

use crate::hash::Hash64;
use crate::{Error, Result};
use crate::plan::camera::Camera;
use crate::source::Heightmap;

/// Frames between jumps of `teleport` when the name gives no count.
pub const DEFAULT_TELEPORT_EVERY: u32 = 120;

/// Height of cruising paths above the smoothed terrain envelope, metres.
pub const CRUISE_HEIGHT_M: f64 = 200.0;

/// Field of view of the cameras a flight makes unless told otherwise, degrees.
pub const DEFAULT_FOV_Y_DEG: f64 = 60.0;

/// The path names [`Path::from_str`] accepts (`teleport` also takes `:K`).
pub const PATH_NAMES: [&str; 5] = ["straight", "circle", "figure8", "dive", "teleport"];

/// Margin kept between every track and the terrain border, as a fraction of the extent.
const BORDER: f64 = 0.08;
/// How far ahead the camera looks, metres, and how far below the horizon (cruising paths).
const LOOK_AHEAD_M: f64 = 1000.0;
const PITCH_DOWN_DEG: f64 = 15.0;
/// Highest start of `dive` above the ground it dives to, metres.
const DIVE_TOP_M: f64 = 20_000.0;
/// Arc-length table resolution of `figure8`.
const FIGURE8_STEPS: usize = 4096;
/// Cells of the terrain envelope along the longer side.
const ENVELOPE_CELLS: f64 = 64.0;

/// A camera path, by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Path {
    /// A straight line across the terrain's diagonal, back and forth.
    Straight,
    /// A circle around the terrain centre.
    Circle,
    /// A figure of eight (lemniscate of Gerono) around the terrain centre.
    Figure8,
    /// From high above down a sloped line to the ground at the centre, then back up the same line.
    Dive,
    /// A jump to a pseudo-random place and heading every `every` frames, cruising straight in between.
    Teleport {
        /// Frames between jumps, at least 1.
        every: u32,
    },
}

impl FromStr for Path {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        let bad = |reason: String| Error::Invalid {
            what: "flight path".into(),
            reason,
        };
        let (head, arg) = match text.split_once(':') {
            Some((h, a)) => (h, Some(a)),
            None => (text, None),
        };
        let path = match head {
            "straight" => Self::Straight,
            "circle" => Self::Circle,
            "figure8" => Self::Figure8,
            "dive" => Self::Dive,
            "teleport" => {
                let every = match arg {
                    None => DEFAULT_TELEPORT_EVERY,
                    Some(k) => match k.trim().parse::<u32>() {
                        Ok(k) if k > 0 => k,
                        _ => {
                            return Err(bad(format!(
                                "`{text}`: teleport:K needs a whole number of frames K >= 1"
                            )))
                        }
                    },
                };
                return Ok(Self::Teleport { every });
            }
            _ => {
                return Err(bad(format!(
                    "`{text}` is not a path ({}, or teleport:K)",
                    PATH_NAMES.join(", ")
                )))
            }
        };
        match arg {
            None => Ok(path),
            Some(_) => Err(bad(format!("`{text}`: only teleport takes a `:` argument"))),
        }
    }
}

impl fmt::Display for Path {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Straight => f.write_str("straight"),
            Self::Circle => f.write_str("circle"),
            Self::Figure8 => f.write_str("figure8"),
            Self::Dive => f.write_str("dive"),
            Self::Teleport { every } => write!(f, "teleport:{every}"),
        }
    }
}

/// A camera path laid over one terrain at one speed: frame index in, [`Camera`] out.
///
/// Everything is computed in [`Flight::new`]; [`Flight::camera`] allocates nothing.
#[derive(Clone)]
pub struct Flight<'a> {
    path: Path,
    speed: f64,
    terrain: &'a Heightmap,
    fov_y_deg: f64,
    min_clearance: f64,
    /// Track box: lower and upper corners of the region every track stays in.
    lo: DVec2,
    hi: DVec2,
    envelope: Envelope,
    /// `figure8`: cumulative arc length at parameter t = i * TAU / FIGURE8_STEPS.
    arc: Vec<f64>,
}

impl fmt::Debug for Flight<'_> {
    // Not derived: the terrain's samples would flood any message that prints a flight.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Flight")
            .field("path", &self.path)
            .field("speed", &self.speed)
            .field("fov_y_deg", &self.fov_y_deg)
            .field("min_clearance", &self.min_clearance)
            .finish_non_exhaustive()
    }
}

/// One point of a track: where, and which way (unit, horizontal).
#[derive(Clone, Copy, Debug)]
struct TrackPoint {
    pos: DVec2,
    heading: DVec2,
}

impl<'a> Flight<'a> {
    /// A flight along `path` at `speed` metres per frame over `terrain`.
    ///
    /// Refuses a speed that is not finite and positive ([`Error::Invalid`] naming the flight speed).
    pub fn new(path: Path, speed: f64, terrain: &'a Heightmap) -> Result<Self> {
        if !(speed.is_finite() && speed > 0.0) {
            return Err(Error::Invalid {
                what: "flight speed".into(),
                reason: format!("{speed} m/frame: must be a finite number above 0"),
            });
        }
        if let Path::Teleport { every: 0 } = path {
            return Err(Error::Invalid {
                what: "flight path".into(),
                reason: "teleport:0: jumps need at least 1 frame between them".into(),
            });
        }
        let (ex, ey) = terrain.extent_m();
        let ext = DVec2::new(ex, ey);
        let spacing = f64::from(terrain.spacing());
        let mut flight = Self {
            path,
            speed,
            terrain,
            fov_y_deg: DEFAULT_FOV_Y_DEG,
            min_clearance: (2.0 * spacing).max(30.0),
            lo: ext * BORDER,
            hi: ext * (1.0 - BORDER),
            envelope: Envelope::new(terrain),
            arc: Vec::new(),
        };
        if path == Path::Figure8 {
            flight.arc = flight.figure8_arc_table();
        }
        Ok(flight)
    }

    /// Sets the field of view of the cameras made (the profile's `view.fov_y_deg`).
    #[must_use]
    pub fn with_fov_y_deg(mut self, fov_y_deg: f64) -> Self {
        self.fov_y_deg = fov_y_deg;
        self
    }

    /// The path flown.
    pub fn path(&self) -> Path {
        self.path
    }

    /// Metres per frame.
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// Least height of the eye above the terrain under it, metres: 30 m or two sample spacings.
    pub fn min_clearance(&self) -> f64 {
        self.min_clearance
    }

    /// Whether the eye jumps (rather than moves `speed` metres) between `frame - 1` and `frame`.
    pub fn jumps_at(&self, frame: u64) -> bool {
        match self.path {
            Path::Teleport { every } => frame > 0 && frame.is_multiple_of(u64::from(every)),
            _ => false,
        }
    }

    /// The camera of frame `frame`: a pure function of the index.
    pub fn camera(&self, frame: u64) -> Camera {
        let s = frame as f64 * self.speed;
        let (eye, look) = match self.path {
            Path::Dive => self.dive(s),
            Path::Teleport { every } => {
                let every = u64::from(every);
                let leg = frame / every;
                let local = (frame % every) as f64 * self.speed;
                self.cruise(self.teleport(leg, local))
            }
            Path::Straight => self.cruise(self.straight(s)),
            Path::Circle => self.cruise(self.circle(s)),
            Path::Figure8 => self.cruise(self.figure8(s)),
        };
        // Paths are laid out relative to the terrain's south-west corner; place them at its origin.
        let (ox, oy) = self.terrain.origin();
        let (x, y) = (eye.x + ox, eye.y + oy);
        let ground = f64::from(self.terrain.height_at_world(x, y));
        let eye = DVec3::new(x, y, eye.z.max(ground + self.min_clearance));
        Camera::new(eye, eye + look * LOOK_AHEAD_M, self.fov_y_deg).unwrap_or_else(|e| {
            panic!(
                "flight {} made an invalid camera at frame {frame}: {e}",
                self.path
            )
        })
    }

    /// Eye on a horizontal track at cruise height, looking ahead and a little down.
    fn cruise(&self, p: TrackPoint) -> (DVec3, DVec3) {
        let z = self.envelope.at(p.pos) + CRUISE_HEIGHT_M;
        let pitch = PITCH_DOWN_DEG.to_radians();
        let look = DVec3::new(
            p.heading.x * pitch.cos(),
            p.heading.y * pitch.cos(),
            -pitch.sin(),
        );
        (p.pos.extend(z), look)
    }

    /// The diagonal of the track box, south-west to north-east, folded back and forth.
    fn straight(&self, s: f64) -> TrackPoint {
        let a = DVec2::new(self.lo.x, self.lo.y + 0.25 * (self.hi.y - self.lo.y));
        let b = DVec2::new(self.hi.x, self.hi.y - 0.25 * (self.hi.y - self.lo.y));
        let len = (b - a).length();
        let dir = (b - a) / len;
        let (d, sign) = fold(s, 0.0, len);
        TrackPoint {
            pos: a + dir * d,
            heading: dir * sign,
        }
    }

    fn centre(&self) -> DVec2 {
        (self.lo + self.hi) * 0.5
    }

    /// Counter-clockwise circle touching the track box's shorter sides.
    fn circle(&self, s: f64) -> TrackPoint {
        let r = 0.5 * (self.hi - self.lo).min_element();
        let a = s / r;
        let (sin, cos) = a.sin_cos();
        TrackPoint {
            pos: self.centre() + r * DVec2::new(cos, sin),
            heading: DVec2::new(-sin, cos),
        }
    }

    /// Lemniscate of Gerono, x = a sin t, y = b sin t cos t, filling the track box.
    fn figure8_at(&self, t: f64) -> TrackPoint {
        let half = 0.5 * (self.hi - self.lo);
        let (a, b) = (half.x, 2.0 * half.y);
        let (sin, cos) = t.sin_cos();
        let vel = DVec2::new(a * cos, b * (2.0 * t).cos());
        TrackPoint {
            pos: self.centre() + DVec2::new(a * sin, b * sin * cos),
            heading: vel.normalize(),
        }
    }

    fn figure8_arc_table(&self) -> Vec<f64> {
        let mut arc = Vec::with_capacity(FIGURE8_STEPS + 1);
        let mut len = 0.0;
        let mut prev = self.figure8_at(0.0).pos;
        arc.push(0.0);
        for i in 1..=FIGURE8_STEPS {
            let p = self.figure8_at(i as f64 * TAU / FIGURE8_STEPS as f64).pos;
            len += (p - prev).length();
            arc.push(len);
            prev = p;
        }
        arc
    }

    /// Arc-length parametrised figure of eight: find t by bisecting the arc table, then interpolate.
    fn figure8(&self, s: f64) -> TrackPoint {
        let total = self.arc[FIGURE8_STEPS];
        let s = s.rem_euclid(total);
        let i = self
            .arc
            .partition_point(|&a| a <= s)
            .clamp(1, FIGURE8_STEPS);
        let (a0, a1) = (self.arc[i - 1], self.arc[i]);
        let f = if a1 > a0 { (s - a0) / (a1 - a0) } else { 0.0 };
        self.figure8_at((i as f64 - 1.0 + f) * TAU / FIGURE8_STEPS as f64)
    }

    /// Leg `leg` of `teleport`: a hashed start and heading, then straight, reflected at the track box.
    fn teleport(&self, leg: u64, s: f64) -> TrackPoint {
        let unit = |salt: u64| {
            let mut h = Hash64::new();
            h.write_u64(leg);
            h.write_u64(salt);
            (h.finish() >> 11) as f64 / (1u64 << 53) as f64
        };
        let start = self.lo + (self.hi - self.lo) * DVec2::new(unit(1), unit(2));
        let (sin, cos) = (TAU * unit(3)).sin_cos();
        let p = start + DVec2::new(cos, sin) * s;
        let (x, sx) = fold(p.x, self.lo.x, self.hi.x);
        let (y, sy) = fold(p.y, self.lo.y, self.hi.y);
        TrackPoint {
            pos: DVec2::new(x, y),
            heading: DVec2::new(cos * sx, sin * sy),
        }
    }

    /// Down a sloped line from high above the south-west to the ground at the centre, and back up.
    ///
    /// The camera faces down the slope both ways, so the climb is the descent played backwards.
    fn dive(&self, s: f64) -> (DVec3, DVec3) {
        let c = self.centre();
        let run = 0.5 * (self.hi - self.lo).min_element();
        let ext = (self.hi - self.lo).max_element() / (1.0 - 2.0 * BORDER);
        let top = DIVE_TOP_M.min(10.0 * ext);
        let (ox, oy) = self.terrain.origin();
        let ground =
            f64::from(self.terrain.height_at_world(c.x + ox, c.y + oy)) + self.min_clearance;
        let bottom = c.extend(ground);
        let (sin, cos) = (210f64).to_radians().sin_cos();
        let start = (c + run * DVec2::new(cos, sin)).extend(ground + top);
        let len = (bottom - start).length();
        let dir = (bottom - start) / len;
        let (d, _) = fold(s, 0.0, len);
        (start + dir * d, dir)
    }
}

/// Folds `v` into `[lo, hi]` as a triangle wave (reflection at both ends); also the sign of its slope.
fn fold(v: f64, lo: f64, hi: f64) -> (f64, f64) {
    let w = hi - lo;
    let t = (v - lo).rem_euclid(2.0 * w);
    if t <= w {
        (lo + t, 1.0)
    } else {
        (lo + 2.0 * w - t, -1.0)
    }
}

/// A smooth upper bound of the terrain: bilinear over a coarse grid of node values, each at least the
/// highest sample anywhere near the node, so the interpolant is never below the terrain.
#[derive(Clone, Debug)]
struct Envelope {
    cell: f64,
    nx: usize,
    ny: usize,
    nodes: Vec<f64>,
}

impl Envelope {
    fn new(terrain: &Heightmap) -> Self {
        let (ex, ey) = terrain.extent_m();
        let spacing = f64::from(terrain.spacing());
        // A cell at least one sample wide keeps every bilinear terrain patch within one cell of its point.
        let cell = (ex.max(ey) / ENVELOPE_CELLS).max(spacing);
        let cells_x = index(ex / cell) + 1;
        let cells_y = index(ey / cell) + 1;
        let mut cell_max = vec![f64::NEG_INFINITY; cells_x * cells_y];
        for v in 0..terrain.height() {
            for u in 0..terrain.width() {
                // Local to the terrain's south-west corner, like the tracks.
                let (x, y) = terrain.grid_to_world(f64::from(u), f64::from(v));
                let (x, y) = (x - terrain.origin().0, y - terrain.origin().1);
                let (cx, cy) = (
                    index(x / cell).min(cells_x - 1),
                    index(y / cell).min(cells_y - 1),
                );
                let slot = &mut cell_max[cy * cells_x + cx];
                *slot = slot.max(f64::from(terrain.at(u, v)));
            }
        }
        let (nx, ny) = (cells_x + 1, cells_y + 1);
        // Node (i, j) sits at the corner shared by cells i-1 and i. Dilate over cells i-3 ..= i+2: after
        // the 3 x 3 blur below, every node still bounds cells i-2 ..= i+1, which hold every sample
        // within one cell of any point next to the node.
        let mut dilated = vec![f64::NEG_INFINITY; nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                let mut m = f64::NEG_INFINITY;
                for cy in j.saturating_sub(3)..(j + 3).min(cells_y) {
                    for cx in i.saturating_sub(3)..(i + 3).min(cells_x) {
                        m = m.max(cell_max[cy * cells_x + cx]);
                    }
                }
                dilated[j * nx + i] = m;
            }
        }
        let mut nodes = vec![0.0; nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                let (mut sum, mut n) = (0.0, 0.0);
                for jj in j.saturating_sub(1)..(j + 2).min(ny) {
                    for ii in i.saturating_sub(1)..(i + 2).min(nx) {
                        sum += dilated[jj * nx + ii];
                        n += 1.0;
                    }
                }
                nodes[j * nx + i] = sum / n;
            }
        }
        Self {
            cell,
            nx,
            ny,
            nodes,
        }
    }

    fn at(&self, p: DVec2) -> f64 {
        let gx = (p.x / self.cell).clamp(0.0, (self.nx - 1) as f64);
        let gy = (p.y / self.cell).clamp(0.0, (self.ny - 1) as f64);
        let (i, j) = (index(gx).min(self.nx - 2), index(gy).min(self.ny - 2));
        let (fx, fy) = (gx - i as f64, gy - j as f64);
        let n = |i: usize, j: usize| self.nodes[j * self.nx + i];
        let a = n(i, j) * (1.0 - fx) + n(i + 1, j) * fx;
        let b = n(i, j + 1) * (1.0 - fx) + n(i + 1, j + 1) * fx;
        a * (1.0 - fy) + b * fy
    }
}

/// The whole part of a small non-negative grid coordinate (negative and NaN give 0).
#[expect(
    clippy::cast_possible_truncation,
    reason = "envelope coordinates are at most a few hundred cells"
)]
fn index(v: f64) -> usize {
    v.max(0.0) as usize
}
