//! Adapter and device selection: a real GPU when there is one, Mesa's lavapipe otherwise.

use super::RenderError;
use tracing::{info, warn};

/// The wgpu device and queue every renderer of the process shares, plus what was chosen.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter_info: wgpu::AdapterInfo,
}

impl Gpu {
    /// Opens the best adapter: a discrete or integrated GPU is preferred, a CPU rasterizer
    /// (lavapipe/llvmpipe) is the fallback. `WGPU_BACKEND` and `WGPU_ADAPTER_NAME` from the
    /// environment override the choice. The chosen adapter is logged.
    pub fn new() -> Result<Gpu, RenderError> {
        pollster::block_on(Self::open())
    }

    async fn open() -> Result<Gpu, RenderError> {
        let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if wgpu::Backends::from_env().is_none() {
            // Vulkan/Metal/DX12 only: the GL backend needs workarounds on llvmpipe and, without a
            // display, fails to initialise EGL noisily. `WGPU_BACKEND=gl` still selects it.
            descriptor.backends = wgpu::Backends::PRIMARY;
        }
        let instance = wgpu::Instance::new(descriptor);
        let adapter = match wgpu::util::initialize_adapter_from_env(&instance, None).await {
            Ok(adapter) => adapter,
            Err(_) => Self::pick_adapter(&instance).await?,
        };
        let adapter_info = adapter.get_info();
        info!(
            adapter = %adapter_info.name,
            backend = ?adapter_info.backend,
            device_type = ?adapter_info.device_type,
            driver = %adapter_info.driver_info,
            "graphics adapter selected"
        );
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("landsketch"),
                required_features: wgpu::Features::empty(),
                // The G-buffer writes 44 bytes per pixel to five targets, more than the downlevel
                // defaults (32 bytes, 4 targets); lavapipe and desktop GPUs allow 128 and 8.
                // A large terrain's vertex buffer (72 bytes a vertex: 3.7 M DEM cells fill
                // wgpu's default 256 MiB) takes what the adapter allows.
                required_limits: wgpu::Limits {
                    max_buffer_size: adapter.limits().max_buffer_size,
                    max_color_attachment_bytes_per_sample: adapter.limits().max_color_attachment_bytes_per_sample,
                    max_color_attachments: adapter.limits().max_color_attachments,
                    ..wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits())
                },
                ..Default::default()
            })
            .await
            .map_err(|e| RenderError::Device { adapter: adapter_info.name.clone(), message: e.to_string() })?;
        // Validation errors are caught with error scopes around each frame; anything that
        // escapes them is logged instead of aborting the process.
        device.on_uncaptured_error(std::sync::Arc::new(|error: wgpu::Error| {
            warn!(error = ?error, "uncaptured wgpu error");
        }));
        Ok(Gpu { device, queue, adapter_info })
    }

    /// Ranks all adapters: discrete GPU, integrated GPU, virtual GPU, then CPU; Vulkan first.
    async fn pick_adapter(instance: &wgpu::Instance) -> Result<wgpu::Adapter, RenderError> {
        let adapters = instance.enumerate_adapters(wgpu::Backends::all()).await;
        let rank = |a: &wgpu::Adapter| {
            let info = a.get_info();
            let ty = match info.device_type {
                wgpu::DeviceType::DiscreteGpu => 0,
                wgpu::DeviceType::IntegratedGpu => 1,
                wgpu::DeviceType::VirtualGpu => 2,
                wgpu::DeviceType::Cpu => 3,
                wgpu::DeviceType::Other => 4,
            };
            (ty, u8::from(info.backend != wgpu::Backend::Vulkan))
        };
        let names: Vec<String> = adapters.iter().map(|a| format!("{:?}", a.get_info())).collect();
        adapters.into_iter().min_by_key(rank).ok_or_else(|| {
            RenderError::NoAdapter(if names.is_empty() { "none enumerated".into() } else { names.join(", ") })
        })
    }

    /// A one-line description of the adapter for logs, benchmarks and the CLI.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?}, {})",
            self.adapter_info.name,
            self.adapter_info.backend,
            self.adapter_info.device_type,
            self.adapter_info.driver_info
        )
    }
}
