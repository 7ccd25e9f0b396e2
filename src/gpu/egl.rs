//! Stage 3, the GPU: a real OpenGL ES 3.0 context made through EGL, for [`super::GpuMode::Strict`].
//!
//! Mesa's EGL hands wgpu's own GL backend a desktop GL 4.5 context whenever it can, which hides GLES 3.0
//! mistakes. Here we make the context ourselves: surfaceless Mesa platform, `OPENGL_ES_API`, an ES3 config,
//! version 3.0, current with no surface. wgpu then wraps it (`wgpu_hal::gles::Adapter::new_external`).
//!
//! The context is current on the thread that made it; [`StrictContext::make_current`] re-binds it before
//! each use, so several contexts may live on one thread.

use std::ffi::c_void;
use std::sync::{Once, OnceLock};

use khronos_egl as egl;

use crate::{Error, Result};

/// `EGL_PLATFORM_SURFACELESS_MESA` (EGL_MESA_platform_surfaceless).
const PLATFORM_SURFACELESS_MESA: egl::Enum = 0x31DD;

/// The Mesa variable that pins the GLES version a context reports.
pub(super) const GLES_OVERRIDE_VAR: &str = "MESA_GLES_VERSION_OVERRIDE";

type EglInstance = egl::DynamicInstance<egl::EGL1_5>;

/// libEGL, loaded once per process (loading is slow and the library is never unloaded anyway).
fn instance() -> Result<&'static EglInstance> {
    static EGL: OnceLock<std::result::Result<EglInstance, String>> = OnceLock::new();
    EGL.get_or_init(|| {
        // SAFETY: loads the system libEGL by its standard name; its symbols are resolved by khronos-egl.
        unsafe { EglInstance::load_required() }
            .map_err(|e| format!("cannot load libEGL.so.1 with EGL 1.5: {e}"))
    })
    .as_ref()
    .map_err(|e| Error::no_adapter(e.clone(), None))
}

/// Sets `MESA_GLES_VERSION_OVERRIDE=3.0` unless the user set it, once, before EGL first starts.
///
/// Without it Mesa reports the highest ES version it can (3.2) even for a 3.0 request; with it the
/// driver exposes exactly the ES 3.0 feature set, so the strict mode sees what a GLES 3.0 phone sees.
/// A user value is kept, so `MESA_GLES_VERSION_OVERRIDE=3.1 clipsat render --gpu strict` still works.
pub(super) fn pin_gles_version() {
    static PIN: Once = Once::new();
    PIN.call_once(|| {
        if std::env::var_os(GLES_OVERRIDE_VAR).is_none() {
            std::env::set_var(GLES_OVERRIDE_VAR, "3.0");
        }
    });
}

/// An EGL display + OpenGL ES 3.0 context, current on the thread that made it. Destroyed on drop.
///
/// The display is not terminated on drop: EGL returns one display per platform, shared by every context
/// in the process (wgpu's GL backend uses the same one), so terminating it would destroy the contexts of
/// every other live [`super::Gpu`]. A process keeps one initialised display, as EGL intends.
pub(super) struct StrictContext {
    egl: &'static EglInstance,
    display: egl::Display,
    context: egl::Context,
}

impl std::fmt::Debug for StrictContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StrictContext")
            .field("display", &self.display.as_ptr())
            .field("context", &self.context.as_ptr())
            .finish()
    }
}

impl StrictContext {
    /// Creates the context and makes it current on this thread.
    pub(super) fn new() -> Result<Self> {
        pin_gles_version();
        let egl = instance()?;
        let fail = |what: &str, e: egl::Error| Error::no_adapter(format!("EGL: {what}"), Some(e.into()));
        let client_ext = egl
            .query_string(None, egl::EXTENSIONS)
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        if !client_ext.contains("EGL_MESA_platform_surfaceless") {
            return Err(Error::no_adapter(
                "EGL has no EGL_MESA_platform_surfaceless (is Mesa's libEGL installed?)",
                None,
            ));
        }
        // SAFETY: the surfaceless platform takes EGL_DEFAULT_DISPLAY and no attributes.
        let display = unsafe {
            egl.get_platform_display(
                PLATFORM_SURFACELESS_MESA,
                egl::DEFAULT_DISPLAY,
                &[egl::ATTRIB_NONE],
            )
        }
        .map_err(|e| fail("eglGetPlatformDisplay(SURFACELESS_MESA)", e))?;
        egl.initialize(display)
            .map_err(|e| fail("eglInitialize", e))?;
        egl.bind_api(egl::OPENGL_ES_API)
            .map_err(|e| fail("eglBindAPI(OPENGL_ES)", e))?;
        // SURFACE_TYPE 0: no window or pbuffer needed, we render into wgpu's framebuffers only.
        let config = egl
            .choose_first_config(
                display,
                &[
                    egl::RENDERABLE_TYPE,
                    egl::OPENGL_ES3_BIT,
                    egl::SURFACE_TYPE,
                    0,
                    egl::NONE,
                ],
            )
            .map_err(|e| fail("eglChooseConfig", e))?
            .ok_or_else(|| Error::no_adapter("EGL: no config with OPENGL_ES3_BIT", None))?;
        let context = egl
            .create_context(
                display,
                config,
                None,
                &[
                    egl::CONTEXT_MAJOR_VERSION,
                    3,
                    egl::CONTEXT_MINOR_VERSION,
                    0,
                    egl::NONE,
                ],
            )
            .map_err(|e| fail("eglCreateContext(OpenGL ES 3.0)", e))?;
        let this = Self {
            egl,
            display,
            context,
        };
        this.make_current()?;
        Ok(this)
    }

    /// Makes this context current on the calling thread (cheap when it already is).
    pub(super) fn make_current(&self) -> Result<()> {
        if self.egl.get_current_context() == Some(self.context) {
            return Ok(());
        }
        self.egl
            .make_current(self.display, None, None, Some(self.context))
            .map_err(|e| Error::gpu("EGL: eglMakeCurrent", e))
    }

    /// The GL function loader wgpu-hal builds its `glow` context from.
    pub(super) fn proc_address(&self, name: &str) -> *const c_void {
        self.egl
            .get_proc_address(name)
            .map_or(std::ptr::null(), |f| f as *const c_void)
    }
}

impl Drop for StrictContext {
    fn drop(&mut self) {
        // Errors are ignored: there is nothing left to do with a context that cannot be released.
        if self.egl.get_current_context() == Some(self.context) {
            let _ = self.egl.make_current(self.display, None, None, None);
        }
        let _ = self.egl.destroy_context(self.display, self.context);
    }
}
