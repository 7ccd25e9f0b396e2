//! The interactive viewer's state (`clipsat view`): held keys, mouse motion and toggle keys in; a camera
//! and the renderer's [`FrameOptions`] out, public types of the library. Pure and windowless, so it is
//! tested without a display; the window (`src/app/cmd/view/`) only maps winit events onto [`Move`] and
//! [`Action`].

use glam::DVec3;

use clipsat::{Camera, DebugView, FrameOptions, LodMode, Result};

/// A key held for flight.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Move {
    /// Along the look direction (W).
    Forward,
    /// Against it (S).
    Back,
    /// Strafe left (A).
    Left,
    /// Strafe right (D).
    Right,
    /// Straight up (E, space).
    Up,
    /// Straight down (Q, C).
    Down,
    /// Turn left (left arrow).
    TurnLeft,
    /// Turn right (right arrow).
    TurnRight,
    /// Look up (up arrow).
    LookUp,
    /// Look down (down arrow).
    LookDown,
    /// Times [`ViewState::FAST`] speed while held (shift).
    Fast,
}

impl Move {
    const COUNT: usize = 11;

    fn index(self) -> usize {
        self as usize
    }
}

/// A one-shot key.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Action {
    /// distance -> sat -> sat-conservative -> exact -> distance (L).
    CycleLod,
    /// Epsilon times 1.25 (]).
    EpsilonUp,
    /// Epsilon over 1.25 ([).
    EpsilonDown,
    /// GC 6.2 morphing on/off (M).
    ToggleMorph,
    /// Frustum culling on/off (K).
    ToggleCull,
    /// normal -> levels -> wireframe (V).
    CycleDebug,
    /// A shading switch on/off (keys 1..4).
    Toggle(Shading),
}

/// The viewer's shading switches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Shading {
    /// SG shading (SAT paper section 5) instead of the basic shading (1).
    Sg,
    /// SG: horizon visibility, soft terrain shadows (2).
    Visibility,
    /// SG: specular (3).
    Specular,
    /// SG: distance fog, where the scene gives its parameters (4).
    Fog,
}

/// What the viewer shades with: [`ViewState::shading`] applied to a scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ShadingSwitches {
    /// SG shading on.
    pub(crate) sg: bool,
    /// Horizon visibility.
    pub(crate) visibility: bool,
    /// Specular.
    pub(crate) specular: bool,
    /// Fog.
    pub(crate) fog: bool,
}

/// The viewer's whole state.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ViewState {
    /// Eye, metres.
    pub(crate) eye: DVec3,
    /// Look azimuth, radians, anticlockwise from east (x).
    pub(crate) yaw: f64,
    /// Look elevation, radians, within +/- [`ViewState::MAX_PITCH`].
    pub(crate) pitch: f64,
    /// Vertical field of view, degrees.
    pub(crate) fov_y_deg: f64,
    /// Clip planes, metres.
    pub(crate) near_far: (f64, f64),
    /// Flight speed, metres per second.
    pub(crate) speed: f64,
    /// Radians per pixel of mouse motion.
    pub(crate) mouse_sensitivity: f64,
    /// LOD mode.
    pub(crate) lod: LodMode,
    /// SAT LOD error bound, pixels.
    pub(crate) epsilon_px: f32,
    /// GC 6.2 morphing.
    pub(crate) morph: bool,
    /// Frustum culling.
    pub(crate) cull: bool,
    /// Debug view.
    pub(crate) debug: DebugView,
    /// The shading switches (keys 1..4); the window re-binds the renderer when they change.
    pub(crate) shading: ShadingSwitches,
    held: [bool; Move::COUNT],
}

impl ViewState {
    /// Speed factor while [`Move::Fast`] is held.
    pub(crate) const FAST: f64 = 5.0;
    /// The steepest look up or down (radians, 85 degrees): the camera needs a defined "up".
    pub(crate) const MAX_PITCH: f64 = 85.0 * std::f64::consts::PI / 180.0;
    /// Turn rate of the arrow keys, radians per second.
    pub(crate) const TURN_RATE: f64 = 1.2;

    /// Starts at `eye` looking along `forward` (a unit vector) through a vertical field of view of
    /// `fov_y_deg` degrees and clip planes `near_far`, flying `speed` m/s, with the SAT LOD bound
    /// `epsilon_px`.
    pub(crate) fn new(
        eye: DVec3,
        forward: DVec3,
        fov_y_deg: f64,
        near_far: (f64, f64),
        speed: f64,
        epsilon_px: f32,
    ) -> Self {
        let f = forward;
        let pitch = f.z.clamp(-1.0, 1.0).asin();
        Self {
            eye,
            yaw: f.y.atan2(f.x),
            pitch: pitch.clamp(-Self::MAX_PITCH, Self::MAX_PITCH),
            fov_y_deg,
            near_far,
            speed,
            mouse_sensitivity: 0.003,
            lod: LodMode::Distance,
            epsilon_px,
            morph: true,
            cull: true,
            debug: DebugView::Normal,
            shading: ShadingSwitches {
                sg: false,
                visibility: true,
                specular: true,
                fog: true,
            },
            held: [false; Move::COUNT],
        }
    }

    /// A flight key went down (`pressed`) or up.
    pub(crate) fn key(&mut self, m: Move, pressed: bool) {
        self.held[m.index()] = pressed;
    }

    /// Whether a flight key is held.
    pub(crate) fn held(&self, m: Move) -> bool {
        self.held[m.index()]
    }

    /// Releases every key (the window lost focus).
    pub(crate) fn release_all(&mut self) {
        self.held = [false; Move::COUNT];
    }

    /// Applies a one-shot key.
    pub(crate) fn action(&mut self, a: Action) {
        match a {
            Action::CycleLod => {
                self.lod = match self.lod {
                    LodMode::Distance => LodMode::Sat,
                    LodMode::Sat => LodMode::SatConservative,
                    LodMode::SatConservative => LodMode::Exact,
                    LodMode::Exact => LodMode::Distance,
                }
            }
            Action::EpsilonUp => self.epsilon_px = (self.epsilon_px * 1.25).min(256.0),
            Action::EpsilonDown => self.epsilon_px = (self.epsilon_px / 1.25).max(0.05),
            Action::ToggleMorph => self.morph = !self.morph,
            Action::ToggleCull => self.cull = !self.cull,
            Action::CycleDebug => self.debug = self.debug.next(),
            Action::Toggle(t) => {
                let s = &mut self.shading;
                let b = match t {
                    Shading::Sg => &mut s.sg,
                    Shading::Visibility => &mut s.visibility,
                    Shading::Specular => &mut s.specular,
                    Shading::Fog => &mut s.fog,
                };
                *b = !*b;
            }
        }
    }

    /// Mouse-look: `dx`, `dy` pixels of motion (right, down) turn right and look down.
    pub(crate) fn look(&mut self, dx: f64, dy: f64) {
        self.yaw -= dx * self.mouse_sensitivity;
        self.pitch =
            (self.pitch - dy * self.mouse_sensitivity).clamp(-Self::MAX_PITCH, Self::MAX_PITCH);
    }

    /// Unit look direction.
    pub(crate) fn forward(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        DVec3::new(cy * cp, sy * cp, sp)
    }

    /// Advances `dt` seconds of flight with the held keys: W/S along the look direction, A/D across it
    /// (horizontal), up/down along z, the arrows turn.
    pub(crate) fn step(&mut self, dt: f64) {
        let held = self.held;
        let axis = |plus: Move, minus: Move| {
            f64::from(u8::from(held[plus.index()])) - f64::from(u8::from(held[minus.index()]))
        };
        self.yaw += axis(Move::TurnLeft, Move::TurnRight) * Self::TURN_RATE * dt;
        self.pitch = (self.pitch + axis(Move::LookUp, Move::LookDown) * Self::TURN_RATE * dt)
            .clamp(-Self::MAX_PITCH, Self::MAX_PITCH);
        let f = self.forward();
        let right = DVec3::new(self.yaw.sin(), -self.yaw.cos(), 0.0);
        let dir = f * axis(Move::Forward, Move::Back)
            + right * axis(Move::Right, Move::Left)
            + DVec3::Z * axis(Move::Up, Move::Down);
        if dir.length_squared() > 0.0 {
            let fast = if self.held(Move::Fast) {
                Self::FAST
            } else {
                1.0
            };
            self.eye += dir.normalize() * self.speed * fast * dt;
        }
    }

    /// Keeps the eye at least `clearance` metres above `ground` (metres).
    pub(crate) fn keep_above(&mut self, ground: f64, clearance: f64) {
        self.eye.z = self.eye.z.max(ground + clearance);
    }

    /// The camera of this state.
    pub(crate) fn camera(&self) -> Result<Camera> {
        Camera::look_at(
            self.eye.to_array(),
            (self.eye + self.forward()).to_array(),
            self.fov_y_deg,
        )?
        .with_clip(self.near_far.0, self.near_far.1)
    }

    /// `base` (the renderer's options) with this state's LOD mode, morph, culling, debug view and
    /// shading switches; the error bound is [`ViewState::epsilon_px`], set apart.
    pub(crate) fn frame_options(&self, base: FrameOptions) -> FrameOptions {
        let mut o = base;
        o.lod = self.lod;
        o.morph = self.morph;
        o.cull = self.cull;
        o.debug = self.debug;
        o.sg = self.shading.sg;
        o.visibility = self.shading.visibility;
        o.specular = self.shading.specular;
        o.fog = self.shading.fog;
        o
    }

    /// One line describing the toggles, for the stats overlay.
    pub(crate) fn describe(&self) -> String {
        format!(
            "{} eps {:.2}px morph {} cull {} view {}",
            self.lod,
            self.epsilon_px,
            on_off(self.morph),
            on_off(self.cull),
            self.debug
        )
    }

    /// The shading switches in one line, for the stats overlay.
    pub(crate) fn describe_shading(&self) -> String {
        let sh = &self.shading;
        if sh.sg {
            format!(
                "shading sg  vis {}  spec {}  fog {}",
                on_off(sh.visibility),
                on_off(sh.specular),
                on_off(sh.fog)
            )
        } else {
            "shading basic".to_string()
        }
    }
}

fn on_off(b: bool) -> &'static str {
    if b {
        "on"
    } else {
        "off"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state() -> ViewState {
        ViewState::new(
            DVec3::new(0.0, 0.0, 100.0),
            DVec3::X,
            60.0,
            (1.0, 1e6),
            10.0,
            1.0,
        )
    }

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-9
    }

    #[test]
    fn starts_looking_where_the_camera_looks() {
        let s = state();
        assert!(close(s.forward(), DVec3::X));
        let c = s.camera().expect("camera");
        let (eye, target) = (DVec3::from(c.eye()), DVec3::from(c.target()));
        assert!(close((target - eye).normalize(), DVec3::X));
        assert!(close(eye, DVec3::new(0.0, 0.0, 100.0)));
    }

    #[test]
    fn wasd_and_up_down_move_the_eye() {
        let mut s = state();
        s.key(Move::Forward, true);
        s.step(1.0);
        assert!(close(s.eye, DVec3::new(10.0, 0.0, 100.0)), "{}", s.eye);
        s.key(Move::Forward, false);
        // Looking east, right is south (-y).
        s.key(Move::Right, true);
        s.step(0.5);
        assert!(close(s.eye, DVec3::new(10.0, -5.0, 100.0)), "{}", s.eye);
        s.key(Move::Right, false);
        s.key(Move::Left, true);
        s.key(Move::Fast, true);
        s.step(0.1);
        assert!(close(s.eye, DVec3::new(10.0, 0.0, 100.0)), "{}", s.eye);
        s.release_all();
        s.key(Move::Up, true);
        s.step(2.0);
        assert!(close(s.eye, DVec3::new(10.0, 0.0, 120.0)), "{}", s.eye);
        // Forward and back cancel; diagonals are not faster.
        s.release_all();
        s.key(Move::Forward, true);
        s.key(Move::Back, true);
        s.step(1.0);
        assert!(close(s.eye, DVec3::new(10.0, 0.0, 120.0)));
        s.key(Move::Back, false);
        s.key(Move::Left, true);
        let before = s.eye;
        s.step(1.0);
        assert!(((s.eye - before).length() - 10.0).abs() < 1e-9);
        s.keep_above(200.0, 30.0);
        assert_eq!(s.eye.z, 230.0);
    }

    #[test]
    fn mouse_look_turns_and_pitch_is_clamped() {
        let mut s = state();
        // Moving the mouse left by a quarter turn looks north.
        let quarter = std::f64::consts::FRAC_PI_2 / s.mouse_sensitivity;
        s.look(-quarter, 0.0);
        assert!(close(s.forward(), DVec3::Y), "{}", s.forward());
        // W now flies north.
        s.key(Move::Forward, true);
        s.step(1.0);
        assert!(close(s.eye, DVec3::new(0.0, 10.0, 100.0)), "{}", s.eye);
        // Mouse up looks up, never past MAX_PITCH, and the camera stays valid.
        s.look(0.0, -1e6);
        assert_eq!(s.pitch, ViewState::MAX_PITCH);
        assert!(s.camera().is_ok());
        s.look(0.0, 2e6);
        assert_eq!(s.pitch, -ViewState::MAX_PITCH);
        assert!(s.camera().is_ok());
        // Arrow keys turn at TURN_RATE.
        let mut t = state();
        t.key(Move::TurnLeft, true);
        t.step(0.5);
        assert!((t.yaw - 0.5 * ViewState::TURN_RATE).abs() < 1e-12);
    }

    #[test]
    fn toggles_cycle_and_reach_the_frame_options() {
        let mut s = state();
        let modes: Vec<LodMode> = (0..5)
            .map(|_| {
                s.action(Action::CycleLod);
                s.lod
            })
            .collect();
        assert_eq!(
            modes,
            [
                LodMode::Sat,
                LodMode::SatConservative,
                LodMode::Exact,
                LodMode::Distance,
                LodMode::Sat
            ]
        );
        s.action(Action::EpsilonUp);
        assert_eq!(s.epsilon_px, 1.25);
        s.action(Action::EpsilonDown);
        s.action(Action::EpsilonDown);
        assert_eq!(s.epsilon_px, 0.8);
        s.action(Action::ToggleMorph);
        s.action(Action::ToggleCull);
        s.action(Action::CycleDebug);
        let o = s.frame_options(FrameOptions::default());
        assert_eq!(
            (o.lod, s.epsilon_px, o.morph, o.cull, o.debug),
            (LodMode::Sat, 0.8, false, false, DebugView::Levels)
        );
        assert!(s.describe().contains("view levels"), "{}", s.describe());
        assert_eq!(s.describe_shading(), "shading basic");
        assert!(!o.sg, "basic shading");
        s.action(Action::Toggle(Shading::Sg));
        s.action(Action::Toggle(Shading::Visibility));
        s.action(Action::Toggle(Shading::Specular));
        let o = s.frame_options(FrameOptions::default());
        assert!(o.sg && !o.visibility && !o.specular && o.fog);
        assert_eq!(
            s.describe_shading(),
            "shading sg  vis off  spec off  fog on"
        );
        s.action(Action::Toggle(Shading::Fog));
        assert!(!s.frame_options(FrameOptions::default()).fog);
    }
}
