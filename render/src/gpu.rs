//! GPU context: adapter selection (a real GPU first, Vulkan on the CPU — Mesa
//! lavapipe — as the fallback), the optional features vwb uses, and the refusal
//! of wgpu's GL backend.
//!
//! Why GL is refused: in wgpu 30 the GL backend writes only the first z slice of
//! a 3D storage texture, which silently breaks every pre-pass that fills a volume.
//! wgpu falls back to GL when no Vulkan driver is installed, so vwb never enables
//! the GL backend and checks the backend of whatever adapter it gets.

use std::fmt;

/// Features vwb asks for where the adapter has them.
pub const OPTIONAL_FEATURES: wgpu::Features = wgpu::Features::FLOAT32_FILTERABLE
    .union(wgpu::Features::FLOAT32_BLENDABLE)
    .union(wgpu::Features::TIMESTAMP_QUERY)
    .union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS)
    .union(wgpu::Features::TEXTURE_FORMAT_16BIT_NORM);

/// The backends vwb may use: everything but GL.
pub const BACKENDS: wgpu::Backends = wgpu::Backends::PRIMARY;

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no usable GPU adapter (Vulkan, Metal or DX12) was found{0}. On Debian/Ubuntu install Mesa's \
         CPU Vulkan driver: apt-get install -y --no-install-recommends mesa-vulkan-drivers libvulkan1"
    )]
    NoAdapter(String),
    #[error(
        "adapter '{0}' uses wgpu's GL backend, which vwb refuses: wgpu 30 on GL writes only the first z \
         slice of a 3D storage texture. Install a Vulkan driver (mesa-vulkan-drivers for the CPU)"
    )]
    GlRefused(String),
    #[error("could not create a device on '{adapter}': {source}")]
    Device {
        adapter: String,
        #[source]
        source: wgpu::RequestDeviceError,
    },
}

/// A device, its queue and what it can do.
#[derive(Clone)]
pub struct GpuContext {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub features: wgpu::Features,
    pub limits: wgpu::Limits,
    /// Set by the device-lost callback: why the device was lost.
    lost: std::sync::Arc<std::sync::Mutex<Option<String>>>,
}

/// Watches `device` for loss; the returned cell holds the reason once it is lost.
fn watch_loss(device: &wgpu::Device) -> std::sync::Arc<std::sync::Mutex<Option<String>>> {
    let lost = std::sync::Arc::new(std::sync::Mutex::new(None));
    let cell = lost.clone();
    device.set_device_lost_callback(move |reason, message| {
        let text = if message.is_empty() {
            format!("{reason:?}")
        } else {
            format!("{reason:?}: {message}")
        };
        log::error!("the GPU device was lost ({text})");
        if let Ok(mut l) = cell.lock() {
            *l = Some(text);
        }
    });
    lost
}

impl fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("GpuContext")
            .field("adapter", &self.info.name)
            .field("backend", &self.info.backend)
            .finish()
    }
}

/// Preference rank of an adapter: lower is better. Real GPUs first, then CPU.
fn rank(info: &wgpu::AdapterInfo) -> u32 {
    match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

/// One-line description of an adapter, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) [Vulkan, Cpu]`.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    let mut s = format!("{} [{:?}, {:?}", info.name, info.backend, info.device_type);
    if !info.driver.is_empty() {
        s.push_str(&format!(", {} {}", info.driver, info.driver_info));
    }
    s.push(']');
    s
}

impl GpuContext {
    /// Headless device on the best adapter. `VWB_ADAPTER=substring` picks an adapter by
    /// name (e.g. `llvmpipe`).
    pub fn new_headless() -> Result<Self, GpuError> {
        pollster::block_on(Self::new_async(
            std::env::var("VWB_ADAPTER").ok().as_deref(),
        ))
    }

    pub async fn new_async(name_filter: Option<&str>) -> Result<Self, GpuError> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = BACKENDS;
        let instance = wgpu::Instance::new(desc);
        let adapter = Self::pick_adapter(&instance, name_filter).await?;
        Self::from_adapter(instance, adapter).await
    }

    async fn pick_adapter(
        instance: &wgpu::Instance,
        name_filter: Option<&str>,
    ) -> Result<wgpu::Adapter, GpuError> {
        let mut adapters = instance.enumerate_adapters(BACKENDS).await;
        adapters.retain(|a| a.get_info().backend != wgpu::Backend::Gl);
        if let Some(f) = name_filter {
            let f = f.to_lowercase();
            adapters.retain(|a| a.get_info().name.to_lowercase().contains(&f));
        }
        adapters.sort_by_key(|a| rank(&a.get_info()));
        adapters.into_iter().next().ok_or_else(|| {
            GpuError::NoAdapter(match name_filter {
                Some(f) => format!(" matching VWB_ADAPTER='{f}'"),
                None => String::new(),
            })
        })
    }

    /// Device on a given adapter with the optional features it supports.
    pub async fn from_adapter(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
    ) -> Result<Self, GpuError> {
        let info = adapter.get_info();
        check_backend(&info)?;
        let features = adapter.features() & OPTIONAL_FEATURES;
        let limits = wanted_limits(&adapter.limits());
        let (device, queue) = adapter
            .request_device(&device_descriptor(features, limits.clone()))
            .await
            .map_err(|source| GpuError::Device {
                adapter: info.name.clone(),
                source,
            })?;
        install_error_handler(&device);
        let lost = watch_loss(&device);
        Ok(Self {
            instance,
            adapter,
            device,
            queue,
            info,
            features,
            limits,
            lost,
        })
    }

    /// Builds a context around a device created elsewhere (e.g. by eframe).
    pub fn from_parts(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
        device: wgpu::Device,
        queue: wgpu::Queue,
    ) -> Result<Self, GpuError> {
        let info = adapter.get_info();
        check_backend(&info)?;
        Ok(Self {
            features: device.features(),
            limits: device.limits(),
            lost: watch_loss(&device),
            instance,
            adapter,
            device,
            queue,
            info,
        })
    }

    pub fn describe(&self) -> String {
        describe(&self.info)
    }

    pub fn has_timestamps(&self) -> bool {
        self.features.contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    pub fn float32_filterable(&self) -> bool {
        self.features.contains(wgpu::Features::FLOAT32_FILTERABLE)
    }

    /// Why the device was lost, once it has been (a driver reset, a removed GPU, or
    /// [`wgpu::Device::destroy`]); every later frame fails with this reason.
    pub fn lost(&self) -> Option<String> {
        self.lost.lock().ok().and_then(|l| l.clone())
    }

    /// Blocks until the GPU is idle.
    pub fn wait(&self) {
        // Errors here mean a lost device; later calls report it.
        let _ = self.device.poll(wgpu::PollType::wait_indefinitely());
    }
}

/// Uploads bytes (x fastest) as an R8Unorm 3D texture for sampling (byte v reads as
/// v/255): brick occupancy, label volumes.
pub fn upload_r8_3d(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    dims: [u32; 3],
    bytes: &[u8],
) -> (wgpu::Texture, wgpu::TextureView) {
    let size = wgpu::Extent3d {
        width: dims[0],
        height: dims[1],
        depth_or_array_layers: dims[2],
    };
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D3,
        format: wgpu::TextureFormat::R8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    queue.write_texture(
        texture.as_image_copy(),
        bytes,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(dims[0]),
            rows_per_image: Some(dims[1]),
        },
        size,
    );
    let view = texture.create_view(&Default::default());
    (texture, view)
}

/// wgpu panics on uncaught validation errors by default; vwb logs them instead
/// (pipeline creation runs inside error scopes and reports its own errors).
pub fn install_error_handler(device: &wgpu::Device) {
    device.on_uncaptured_error(std::sync::Arc::new(|e| {
        // the error and its causes (its Display is the first line only)
        let mut message = e.to_string();
        let mut cause = std::error::Error::source(&e);
        while let Some(c) = cause {
            message.push_str(&format!(": {c}"));
            cause = c.source();
        }
        log::error!("wgpu: {message}");
    }));
}

/// Refuses the GL backend.
pub fn check_backend(info: &wgpu::AdapterInfo) -> Result<(), GpuError> {
    if info.backend == wgpu::Backend::Gl {
        return Err(GpuError::GlRefused(info.name.clone()));
    }
    Ok(())
}

/// Limits vwb asks for: the defaults, raised to what the adapter offers for
/// textures, bindings and inter-stage variables.
pub fn wanted_limits(adapter: &wgpu::Limits) -> wgpu::Limits {
    let base = wgpu::Limits::default();
    wgpu::Limits {
        max_texture_dimension_2d: adapter.max_texture_dimension_2d,
        max_texture_dimension_3d: adapter.max_texture_dimension_3d,
        max_texture_array_layers: adapter.max_texture_array_layers,
        max_bind_groups: adapter.max_bind_groups.max(base.max_bind_groups),
        max_bindings_per_bind_group: adapter.max_bindings_per_bind_group,
        max_sampled_textures_per_shader_stage: adapter.max_sampled_textures_per_shader_stage,
        max_samplers_per_shader_stage: adapter.max_samplers_per_shader_stage,
        max_storage_textures_per_shader_stage: adapter.max_storage_textures_per_shader_stage,
        max_storage_buffers_per_shader_stage: adapter.max_storage_buffers_per_shader_stage,
        max_uniform_buffers_per_shader_stage: adapter.max_uniform_buffers_per_shader_stage,
        max_storage_buffer_binding_size: adapter.max_storage_buffer_binding_size,
        max_buffer_size: adapter.max_buffer_size,
        // the slice vertices pass the fragments the parameters as flat outputs
        // (composer.rs `routed_params`)
        max_inter_stage_shader_variables: adapter
            .max_inter_stage_shader_variables
            .max(base.max_inter_stage_shader_variables),
        ..base
    }
    .using_resolution(adapter.clone())
}

/// The device descriptor vwb uses (also for eframe's device).
pub fn device_descriptor(
    features: wgpu::Features,
    limits: wgpu::Limits,
) -> wgpu::DeviceDescriptor<'static> {
    wgpu::DeviceDescriptor {
        label: Some("vwb device"),
        required_features: features,
        required_limits: limits,
        experimental_features: wgpu::ExperimentalFeatures::disabled(),
        memory_hints: wgpu::MemoryHints::Performance,
        trace: wgpu::Trace::Off,
    }
}
