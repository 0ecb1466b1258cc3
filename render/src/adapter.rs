//! Finding a wgpu adapter and device: for headless rendering, or for a
//! window's or canvas's surface.
//!
//! Prefers Vulkan (a real GPU, or Mesa's lavapipe on CPU-only machines) and
//! falls back to GL (llvmpipe). `FARFIELD_BACKEND=vulkan|gl` forces one.
//! Software adapters are always accepted: the CI machines have no GPU.

use std::ffi::OsString;

use anyhow::bail;

/// Environment variable that forces a backend: `vulkan` or `gl`.
pub const BACKEND_ENV: &str = "FARFIELD_BACKEND";

/// Environment variable that lets GPU tests pass without any adapter
/// (`FARFIELD_ALLOW_NO_GPU=1`); without it a missing adapter fails them.
pub const ALLOW_NO_GPU_ENV: &str = "FARFIELD_ALLOW_NO_GPU";

/// Mesa's Vulkan device-select layer's own off switch (the
/// `disable_environment` of its manifest): variable and value.
pub const DEVICE_SELECT_OFF: (&str, &str) = ("NODEVICE_SELECT", "1");

/// Whether Mesa's device-select layer should be switched off, reading the
/// environment through `var`: when there is no desktop session to select a
/// device for (neither `XDG_RUNTIME_DIR` nor `WAYLAND_DISPLAY` is set) and
/// the user has neither asked the layer for a device
/// (`MESA_VK_DEVICE_SELECT`) nor set the switch already. On such a machine
/// (ssh, CI, a container, a service) the layer asks libwayland for a
/// display, which prints `error: XDG_RUNTIME_DIR is invalid or not set in
/// the environment.` twice: an "error" that is none, as the adapter opens
/// either way, but the first thing a user of a headless server would read.
pub fn device_select_unwanted(var: impl Fn(&str) -> Option<OsString>) -> bool {
    let set = |name: &str| var(name).is_some_and(|v| !v.is_empty());
    !set("XDG_RUNTIME_DIR")
        && !set("WAYLAND_DISPLAY")
        && !set("MESA_VK_DEVICE_SELECT")
        && !set(DEVICE_SELECT_OFF.0)
}

/// Sets [`DEVICE_SELECT_OFF`] when [`device_select_unwanted`] says so.
///
/// # Safety
///
/// Changes the process environment, so it must run before any other thread
/// exists (first thing in `main`): another thread reading the environment
/// at the same time is undefined behaviour in glibc.
pub unsafe fn quiet_device_select_when_headless() {
    if device_select_unwanted(|name| std::env::var_os(name)) {
        let (name, value) = DEVICE_SELECT_OFF;
        // SAFETY: the caller guarantees that no other thread is running.
        unsafe { std::env::set_var(name, value) };
    }
}

/// An opened device with its queue and what it runs on.
#[derive(Debug)]
pub(crate) struct Gpu {
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
}

/// The backends to try, in order, honouring [`BACKEND_ENV`].
fn backends_to_try() -> anyhow::Result<Vec<wgpu::Backends>> {
    let choice = std::env::var(BACKEND_ENV).unwrap_or_default();
    Ok(match choice.trim().to_ascii_lowercase().as_str() {
        "" | "auto" => vec![wgpu::Backends::VULKAN, wgpu::Backends::GL],
        "vulkan" | "vk" => vec![wgpu::Backends::VULKAN],
        "gl" | "gles" | "opengl" => vec![wgpu::Backends::GL],
        other => bail!("{BACKEND_ENV}={other} is not one of: vulkan, gl"),
    })
}

/// Opens the first adapter found, Vulkan before GL, with every limit it has.
pub(crate) fn open() -> anyhow::Result<Gpu> {
    let mut tried = Vec::new();
    for backends in backends_to_try()? {
        let desc = wgpu::InstanceDescriptor {
            backends,
            ..wgpu::InstanceDescriptor::new_without_display_handle_from_env()
        };
        let instance = wgpu::Instance::new(desc);
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        };
        let adapter = match pollster::block_on(instance.request_adapter(&options)) {
            Ok(adapter) => adapter,
            Err(e) => {
                tried.push(format!("{backends:?}: {e}"));
                continue;
            }
        };
        match pollster::block_on(open_device(adapter)) {
            Ok(gpu) => return Ok(gpu),
            Err(e) => tried.push(e),
        }
    }
    bail!(
        "no GPU adapter found ({}). Without a GPU install Mesa's software drivers \
         (Debian: `apt-get install mesa-vulkan-drivers` for lavapipe, or libegl-mesa0 and \
         libgl1-mesa-dri for llvmpipe GL); {BACKEND_ENV}=vulkan|gl picks a backend",
        tried.join("; ")
    )
}

/// Opens `adapter`'s device with every limit it has; the error names it.
async fn open_device(adapter: wgpu::Adapter) -> Result<Gpu, String> {
    let info = adapter.get_info();
    let device = adapter
        .request_device(&wgpu::DeviceDescriptor {
            label: Some("farfield"),
            required_limits: adapter.limits(),
            memory_hints: wgpu::MemoryHints::Performance,
            ..Default::default()
        })
        .await;
    match device {
        Ok((device, queue)) => Ok(Gpu {
            adapter,
            device,
            queue,
            info,
        }),
        Err(e) => Err(format!("{}: cannot open a device: {e}", describe(&info))),
    }
}

/// An adapter and device of `instance` that can draw into `surface`.
pub(crate) async fn open_for_surface(
    instance: &wgpu::Instance,
    surface: &wgpu::Surface<'_>,
) -> anyhow::Result<Gpu> {
    let options = wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: Some(surface),
        apply_limit_buckets: false,
    };
    let adapter = instance
        .request_adapter(&options)
        .await
        .map_err(|e| anyhow::anyhow!("no GPU adapter can draw to this surface: {e}"))?;
    open_device(adapter).await.map_err(anyhow::Error::msg)
}

/// Describes an adapter as "name / backend (driver info)".
pub(crate) fn describe(info: &wgpu::AdapterInfo) -> String {
    let mut s = format!("{} / {:?}", info.name, info.backend);
    if !info.driver_info.is_empty() {
        s.push_str(&format!(" ({})", info.driver_info));
    }
    s
}

/// Whether a missing adapter may be tolerated ([`ALLOW_NO_GPU_ENV`] is `1`).
pub(crate) fn no_gpu_allowed() -> bool {
    std::env::var(ALLOW_NO_GPU_ENV).is_ok_and(|v| v.trim() == "1")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unwanted(vars: &[(&str, &str)]) -> bool {
        device_select_unwanted(|name| {
            vars.iter()
                .find(|(n, _)| *n == name)
                .map(|(_, v)| OsString::from(v))
        })
    }

    #[test]
    fn device_select_is_switched_off_only_without_a_session_or_a_choice() {
        assert!(unwanted(&[]), "a headless machine");
        assert!(unwanted(&[("XDG_RUNTIME_DIR", "")]), "set but empty");
        assert!(!unwanted(&[("XDG_RUNTIME_DIR", "/run/user/1000")]));
        assert!(!unwanted(&[("WAYLAND_DISPLAY", "wayland-0")]));
        assert!(!unwanted(&[("MESA_VK_DEVICE_SELECT", "10de:2684")]));
        assert!(
            !unwanted(&[("NODEVICE_SELECT", "0")]),
            "the user's value stays"
        );
    }
}
