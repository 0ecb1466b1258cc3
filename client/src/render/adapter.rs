//! Finding a wgpu adapter and device for headless rendering.
//!
//! Prefers Vulkan (a real GPU, or Mesa's lavapipe on CPU-only machines) and
//! falls back to GL (llvmpipe). `FARFIELD_BACKEND=vulkan|gl` forces one.
//! Software adapters are always accepted: the CI machines have no GPU.

use anyhow::bail;

/// Environment variable that forces a backend: `vulkan` or `gl`.
pub const BACKEND_ENV: &str = "FARFIELD_BACKEND";

/// Environment variable that lets GPU tests pass without any adapter
/// (`FARFIELD_ALLOW_NO_GPU=1`); without it a missing adapter fails them.
pub const ALLOW_NO_GPU_ENV: &str = "FARFIELD_ALLOW_NO_GPU";

/// An opened device with its queue and what it runs on.
#[derive(Debug)]
pub(crate) struct Gpu {
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
        let info = adapter.get_info();
        let device = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("farfield"),
            required_limits: adapter.limits(),
            memory_hints: wgpu::MemoryHints::Performance,
            ..Default::default()
        }));
        match device {
            Ok((device, queue)) => {
                return Ok(Gpu {
                    device,
                    queue,
                    info,
                });
            }
            Err(e) => tried.push(format!("{}: cannot open a device: {e}", describe(&info))),
        }
    }
    bail!(
        "no GPU adapter found ({}). Without a GPU install Mesa's software drivers \
         (Debian: `apt-get install mesa-vulkan-drivers` for lavapipe, or libegl-mesa0 and \
         libgl1-mesa-dri for llvmpipe GL); {BACKEND_ENV}=vulkan|gl picks a backend",
        tried.join("; ")
    )
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
