//! The Khronos validation layer's check can fail: a deliberate misuse below wgpu's own validation (a
//! zero-sized `VkBuffer`, VUID-VkBufferCreateInfo-size-00912) is reported through
//! `clipsat::gpu::validation`'s sink into the file `CLIPSAT_VALIDATION_LOG` names, the file `.ci/run`
//! fails on. The misuse runs in a child process with a log file of its own, so the run's file stays empty.
//! Vulkan passes only (`CLIPSAT_GPU=vulkan`); it needs the layer (`vulkan-validationlayers`, `.ci/setup`).

use std::path::Path;
use std::process::Command;

use crate::render_support::{on_vulkan, strict};
use clipsat::gpu::validation::LOG_VAR;

/// The misuse's VUID: a buffer's size must be greater than 0.
const VUID: &str = "VUID-VkBufferCreateInfo-size-00912";

#[test]
fn the_validation_layer_reports_a_deliberate_misuse() {
    if !on_vulkan() {
        return;
    }
    let log = Path::new(env!("CARGO_TARGET_TMPDIR")).join("validation-misuse.log");
    let _ = std::fs::remove_file(&log);
    let exe = std::env::current_exe().expect("the test binary's path");
    let out = Command::new(exe)
        .args([
            "--ignored",
            "--exact",
            "validation::deliberate_misuse",
            "--test-threads",
            "1",
        ])
        .env(LOG_VAR, &log)
        .output()
        .expect("run the misuse in a child process");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "the child failed: {stderr}");
    let text = std::fs::read_to_string(&log).unwrap_or_else(|e| {
        panic!(
            "{}: {e}: the layer reported nothing (is vulkan-validationlayers installed? \
             `bash .ci/setup`); child's stderr: {stderr}",
            log.display()
        )
    });
    assert!(text.contains(VUID), "{text}");
    assert!(text.starts_with("ERROR"), "{text}");
}

/// The misuse itself: run by the test above under its own log file, never in the run's.
#[test]
#[ignore = "a deliberate Vulkan misuse, run by the_validation_layer_reports_a_deliberate_misuse"]
fn deliberate_misuse() {
    assert!(on_vulkan(), "run with CLIPSAT_GPU=vulkan");
    let gpu = strict();
    // SAFETY: the raw device outlives the buffer, which is destroyed at once and never bound or used.
    unsafe {
        let hal = gpu
            .device()
            .as_hal::<wgpu_hal::api::Vulkan>()
            .expect("a Vulkan device");
        let raw = hal.raw_device();
        let info = ash::vk::BufferCreateInfo::default()
            .size(0)
            .usage(ash::vk::BufferUsageFlags::TRANSFER_DST)
            .sharing_mode(ash::vk::SharingMode::EXCLUSIVE);
        if let Ok(buffer) = raw.create_buffer(&info, None) {
            raw.destroy_buffer(buffer, None);
        }
    }
}
