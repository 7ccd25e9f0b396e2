//! Stage 3, the GPU: the Khronos validation layer's reports, kept where a test run can fail on them.
//!
//! wgpu turns the layer on for an instance made with [`wgpu::InstanceFlags::VALIDATION`] and passes each
//! of its messages to the `log` crate (target `wgpu_hal::vulkan::instance`), where nobody reads them unless
//! the program installed a logger. With [`LOG_VAR`] set to a file, [`install_from_env`] installs one that
//! appends every validation or performance message of warning or error severity to that file (one process
//! or many: each line is one `O_APPEND` write) and to stderr; [`crate::gpu::Gpu`]'s Vulkan devices then ask
//! for the layer themselves. `.ci/run` sets it for the Vulkan passes and fails when the file is not empty.
//!
//! A test instrument: an embedder never needs it, and nothing happens without the variable.

use std::io::Write as _;
use std::path::PathBuf;
use std::sync::OnceLock;

/// The variable naming the file the layer's reports are appended to.
pub const LOG_VAR: &str = "CLIPSAT_VALIDATION_LOG";

/// Where the layer's messages arrive: wgpu-hal's Vulkan debug messenger.
const TARGET: &str = "wgpu_hal::vulkan::instance";

struct Sink {
    path: PathBuf,
    /// Whether the record before was one kept: the messenger logs a message's queue, command-buffer and
    /// object labels as records of their own, each starting with a tab.
    last_kept: std::sync::atomic::AtomicBool,
}

impl log::Log for Sink {
    fn enabled(&self, meta: &log::Metadata<'_>) -> bool {
        meta.level() <= log::Level::Warn && meta.target() == TARGET
    }

    fn log(&self, record: &log::Record<'_>) {
        use std::sync::atomic::Ordering;
        if !self.enabled(record.metadata()) {
            return;
        }
        let text = record.args().to_string();
        // The messenger's first line is `{message type:?} [{id name} (0x{id})]`: the loader's own messages
        // are GENERAL; the layer's are VALIDATION or PERFORMANCE.
        let kept = if text.starts_with('\t') {
            self.last_kept.load(Ordering::Relaxed)
        } else {
            let head = text.split(" [").next().unwrap_or("");
            head.contains("VALIDATION") || head.contains("PERFORMANCE")
        };
        self.last_kept.store(kept, Ordering::Relaxed);
        if !kept {
            return;
        }
        let line = format!(
            "{} pid {}: {}\n",
            record.level(),
            std::process::id(),
            text.replace('\n', " ")
        );
        eprint!("validation layer: {line}");
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&self.path);
        match file {
            Ok(mut f) => {
                if let Err(e) = f.write_all(line.as_bytes()) {
                    eprintln!("{}: {e}", self.path.display());
                }
            }
            Err(e) => eprintln!("{}: {e}", self.path.display()),
        }
    }

    fn flush(&self) {}
}

/// With [`LOG_VAR`] set, installs the logger that keeps the layer's reports (once per process) and
/// returns true; without it, or when the program has a logger of its own, returns false (the latter
/// said on stderr, since the reports then go to that logger).
pub fn install_from_env() -> bool {
    static INSTALLED: OnceLock<bool> = OnceLock::new();
    *INSTALLED.get_or_init(|| {
        let Some(path) = std::env::var_os(LOG_VAR).filter(|p| !p.is_empty()) else {
            return false;
        };
        let sink = Box::leak(Box::new(Sink {
            path: PathBuf::from(path),
            last_kept: std::sync::atomic::AtomicBool::new(false),
        }));
        if log::set_logger(sink).is_err() {
            eprintln!(
                "{LOG_VAR} is set but this program has a logger of its own: the validation layer's \
                 reports go to it"
            );
            return false;
        }
        log::set_max_level(log::LevelFilter::Warn);
        true
    })
}
