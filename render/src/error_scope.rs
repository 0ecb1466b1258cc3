//! Validation errors of one stretch of GPU work, as a `Result`.
//!
//! Natively a pushed error scope is popped and waited for at once (the
//! future is ready when the device has checked the work). A browser's
//! WebGPU answers that future only after the current task yields, so
//! blocking on it would hang the page: there no scope is pushed, and
//! validation errors reach the device's uncaptured-error handler, which
//! the viewer sets (`Device::on_uncaptured_error`).

/// An open scope, or nothing where scopes cannot be waited for.
#[derive(Debug)]
pub(crate) struct ValidationScope(Option<wgpu::ErrorScopeGuard>);

impl ValidationScope {
    pub fn push(device: &wgpu::Device) -> Self {
        if cfg!(target_arch = "wasm32") {
            Self(None)
        } else {
            Self(Some(device.push_error_scope(wgpu::ErrorFilter::Validation)))
        }
    }

    /// The first validation error since [`Self::push`], where it can be known.
    pub fn pop(self) -> Option<wgpu::Error> {
        self.0.and_then(|scope| pollster::block_on(scope.pop()))
    }
}
