//! Stage 3, the GPU: wgpu's errors of clipsat's own GPU work returned as [`Error::Gpu`], through error
//! scopes on the caller's device, never through the device's uncaptured-error handler (which is the
//! caller's: wgpu's default one panics, and clipsat replaces no handler the caller set).
//!
//! wgpu's error scopes are per device and per thread: what `f` does on this thread between the push and
//! the pop is captured, nothing of other threads. A scope captures the first error of its filter; the
//! three filters (validation, out of memory, internal) each get one. wgpu boxes each pop's future (three
//! small allocations a call, on wgpu's side); the pop itself is polled here once, without an executor,
//! since wgpu's native backends answer at once.

use std::future::Future;
use std::pin::pin;
use std::task::{Context, Poll, Waker};

use crate::{Error, Result};

/// Runs `f` inside validation, out-of-memory and internal error scopes on `device`: the first wgpu error
/// it caused comes back as [`Error::Gpu`] naming `action` (with wgpu's error as its source), before `f`'s
/// own result. A lost device is not an error here: wgpu drops the errors of a lost device and reports
/// the loss through [`wgpu::Device::set_device_lost_callback`], the caller's.
pub fn scoped<T>(device: &wgpu::Device, action: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
    let internal = device.push_error_scope(wgpu::ErrorFilter::Internal);
    let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let out = f();
    // Popped in reverse order of the pushes, as wgpu requires.
    let v = ready(validation.pop());
    let o = ready(oom.pop());
    let i = ready(internal.pop());
    match v.or(o).or(i) {
        Some(e) => Err(Error::gpu(action, e)),
        None => out,
    }
}

/// The output of a future that is ready when first polled (wgpu-core's error scope pops), or else of
/// waiting for it (a backend that answers later).
fn ready<F: Future>(future: F) -> F::Output {
    let mut future = pin!(future);
    match future
        .as_mut()
        .poll(&mut Context::from_waker(Waker::noop()))
    {
        Poll::Ready(out) => out,
        Poll::Pending => pollster::block_on(future),
    }
}
