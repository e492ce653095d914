//! WebGPU through wgpu: acquiring an adapter and device without a window ([`Gpu`]), and the compute pipelines
//! that voxelize ([`voxelize`]) and compact ([`compact`]) on it. Used by the CLI, the tests and the app alike.

pub mod colour;
pub mod compact;
pub mod distance;
pub mod group;
mod groups;
mod plan;
pub mod query;
mod readback;
mod run;
pub mod solid;
mod sparse;
mod util;
pub mod voxelize;
pub(crate) mod wgsl;

pub use readback::watchdog;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
pub use voxelize::Traffic;

/// Devices [`Gpu::from_adapter_with_limits`] has opened in this process.
static DEVICES_OPENED: AtomicUsize = AtomicUsize::new(0);

/// How many GPU devices meshvox has opened in this process (devices a client opened and handed over with
/// [`Gpu::from_parts`], such as the viewer's, are not counted). A device costs memory and, on a software
/// adapter, seconds of pipeline compilation: clients that should open one per process check it with this.
pub fn devices_opened() -> usize {
    DEVICES_OPENED.load(Ordering::Relaxed)
}

/// What the adapter is, for stats and messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdapterSummary {
    pub name: String,
    pub backend: String,
    pub device_type: String,
    pub driver: String,
}

impl AdapterSummary {
    pub fn from_info(info: &wgpu::AdapterInfo) -> AdapterSummary {
        AdapterSummary {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            driver: [info.driver.as_str(), info.driver_info.as_str()]
                .into_iter()
                .filter(|s| !s.is_empty())
                .collect::<Vec<_>>()
                .join(" "),
        }
    }

    /// Whether the adapter is a software implementation on the CPU (lavapipe, SwiftShader, WARP): compute on
    /// it runs on the same cores as the CPU voxelizer, which is faster there.
    pub fn is_software(&self) -> bool {
        self.device_type == format!("{:?}", wgpu::DeviceType::Cpu)
    }

    /// A file-name-safe name of backend and adapter, such as `vulkan-llvmpipe`: screenshot goldens are only
    /// comparable on the same one and carry it in their names.
    pub fn slug(&self) -> String {
        let name = self.name.split_whitespace().next().unwrap_or("unknown").to_lowercase();
        format!("{}-{}", self.backend.to_lowercase(), name)
            .replace(|c: char| !c.is_ascii_alphanumeric() && c != '-', "")
    }
}

impl std::fmt::Display for AdapterSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({}", self.name, self.backend)?;
        if !self.driver.is_empty() {
            write!(f, ", {}", self.driver)?;
        }
        write!(f, ")")
    }
}

/// What wgpu said when it found no adapter, without the backends this build never has ("metal support not compiled
/// in"): on a machine without the Vulkan loader, "vulkan drivers/libraries could not be loaded, gl drivers/libraries
/// could not be loaded".
fn why_no_adapter(wgpu_says: &str) -> String {
    let reasons = wgpu_says.split_once("; ").map_or(wgpu_says, |(_, reasons)| reasons);
    let kept: Vec<&str> = reasons.split(", ").filter(|r| !r.ends_with("not compiled in")).collect();
    if kept.is_empty() { wgpu_says.to_string() } else { kept.join(", ") }
}

/// Errors of the GPU path. Each message says what to do where there is something to do.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter found ({0}); use {cpu}, or install the Vulkan loader and a driver (Debian, Ubuntu: libvulkan1 mesa-vulkan-drivers)", cpu = crate::names::Setting::Backend.with("cpu"))]
    NoAdapter(String),
    #[error("this device has no compute shaders (WebGL2); use {}", crate::names::Setting::Backend.with("cpu"))]
    NoCompute,
    #[error("the GPU adapter refused a device: {0}")]
    RequestDevice(String),
    #[error(
        "{what} needs {}, but this adapter allows at most {} per buffer",
        crate::memory::human(*needed),
        crate::memory::human(*limit)
    )]
    TooLarge { what: String, needed: u64, limit: u64 },
    #[error("the GPU ran out of memory: {0}")]
    OutOfMemory(String),
    #[error("GPU error: {0}")]
    Device(String),
    #[error("the GPU device was lost ({0})")]
    DeviceLost(String),
    #[error(
        "the GPU did not finish within {0:.1} s and was given up on (a hung device or a driver fault; \
         MESHVOX_GPU_TIMEOUT sets the limit in seconds)"
    )]
    Timeout(f64),
    #[error("{voxels} voxels were drawn on {adapter}, but the picture read back shows {what}")]
    BlankPicture { voxels: u32, adapter: String, what: String },
    #[error(transparent)]
    Grid(#[from] crate::voxel::GridError),
}

impl GpuError {
    /// Whether the device itself failed (lost, out of memory, hung, or an error outside any request's
    /// validation), as opposed to a request it cannot take: either way the CPU can stand in.
    pub fn is_device_failure(&self) -> bool {
        matches!(self, GpuError::OutOfMemory(_) | GpuError::Device(_) | GpuError::DeviceLost(_) | GpuError::Timeout(_))
    }
}

/// A wgpu error in one line with its cause: `Display` alone says only "Validation Error".
pub(crate) fn describe(e: &wgpu::Error) -> String {
    let text = match e {
        wgpu::Error::Validation { description, .. } => description.clone(),
        other => {
            let mut text = other.to_string();
            let mut source = std::error::Error::source(other);
            while let Some(s) = source {
                text.push_str(&format!(": {s}"));
                source = s.source();
            }
            text
        }
    };
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// What a device said outside any error scope: that it was lost, or an error nobody captured. wgpu's default
/// for an uncaptured error is a panic, which would take the viewer or the browser tab down with it.
#[derive(Default)]
struct Health {
    lost: Mutex<Option<String>>,
    uncaptured: Mutex<Option<String>>,
}

/// An adapter, its device and queue, ready for compute. Cloning shares the same device.
#[derive(Clone)]
pub struct Gpu {
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub summary: AdapterSummary,
    /// Whether compute passes can be timed with timestamp queries.
    pub timestamps: bool,
    health: Arc<Health>,
}

impl Gpu {
    /// Acquires the default adapter without any window or surface. `WGPU_BACKEND` (vulkan, gl, …) and
    /// `WGPU_ADAPTER_NAME` pick another one.
    pub async fn new() -> Result<Gpu, GpuError> {
        Self::from_adapter(Self::adapter().await?).await
    }

    /// The adapter [`Gpu::new`] would open, without opening a device on it (which is where the time goes).
    pub async fn adapter() -> Result<wgpu::Adapter, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        wgpu::util::initialize_adapter_from_env_or_default(&instance, None)
            .await
            .map_err(|e| GpuError::NoAdapter(why_no_adapter(&e.to_string())))
    }

    /// Blocking [`Gpu::new`] for native callers.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn new_blocking() -> Result<Gpu, GpuError> {
        pollster::block_on(Self::new())
    }

    /// Blocking [`Gpu::adapter`] for native callers.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn adapter_blocking() -> Result<wgpu::Adapter, GpuError> {
        pollster::block_on(Self::adapter())
    }

    /// Opens a device on `adapter` with its full limits and, where available, timestamp queries.
    pub async fn from_adapter(adapter: wgpu::Adapter) -> Result<Gpu, GpuError> {
        let limits = adapter.limits();
        Self::from_adapter_with_limits(adapter, limits).await
    }

    /// [`Gpu::from_adapter`] with other limits (at most the adapter's): small ones stand in for a small GPU in
    /// the tests of the slab, batch and too-large paths.
    pub async fn from_adapter_with_limits(adapter: wgpu::Adapter, limits: wgpu::Limits) -> Result<Gpu, GpuError> {
        let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("meshvox"),
                required_features: features,
                required_limits: limits,
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::RequestDevice(e.to_string()))?;
        DEVICES_OPENED.fetch_add(1, Ordering::Relaxed);
        Ok(Gpu::from_parts(adapter, device, queue))
    }

    /// Wraps a device someone else opened (eframe's, egui_kittest's); timestamps are used if it has them.
    /// Device loss and errors outside any error scope are recorded (and logged) instead of panicking; see
    /// [`Gpu::check`].
    pub fn from_parts(adapter: wgpu::Adapter, device: wgpu::Device, queue: wgpu::Queue) -> Gpu {
        let summary = AdapterSummary::from_info(&adapter.get_info());
        let timestamps = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let health = Arc::new(Health::default());
        let on_lost = Arc::clone(&health);
        device.set_device_lost_callback(move |reason, message| {
            log::error!("wgpu: device lost ({reason:?}): {message}");
            if let Ok(mut lost) = on_lost.lost.lock() {
                *lost = Some(if message.is_empty() { format!("{reason:?}") } else { message });
            }
        });
        let on_error = Arc::clone(&health);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            log::error!("wgpu: {e}");
            if let Ok(mut slot) = on_error.uncaptured.lock() {
                slot.get_or_insert_with(|| describe(&e));
            }
        }));
        Gpu { adapter, device, queue, summary, timestamps, health }
    }

    /// `Err` once the device has been lost, or with the first error it reported outside an error scope since
    /// the last check. Callers check before and after a piece of work: a lost device explains any other failure.
    pub fn check(&self) -> Result<(), GpuError> {
        // wgpu runs the lost callback when the device is next maintained; a non-blocking poll does that now.
        // (In the browser the callback comes from the event loop, and the poll is a no-op.)
        let _ = self.device.poll(wgpu::PollType::Poll);
        if let Some(reason) = self.health.lost.lock().ok().and_then(|l| l.clone()) {
            return Err(GpuError::DeviceLost(reason));
        }
        match self.health.uncaptured.lock().ok().and_then(|mut u| u.take()) {
            Some(message) => Err(GpuError::Device(message)),
            None => Ok(()),
        }
    }

    /// Whether the device has been lost (it never comes back: open a new [`Gpu`]).
    pub fn is_lost(&self) -> bool {
        self.health.lost.lock().is_ok_and(|l| l.is_some())
    }

    /// Whether this device runs compute shaders (WebGL2 does not: the app then voxelizes on the CPU).
    pub fn has_compute(&self) -> bool {
        let l = self.device.limits();
        l.max_compute_workgroups_per_dimension > 0 && l.max_storage_buffers_per_shader_stage > 0
    }

    /// Largest buffer this device can bind as one storage binding (and allocate).
    pub fn max_binding_bytes(&self) -> u64 {
        let l = self.device.limits();
        l.max_storage_buffer_binding_size.min(l.max_buffer_size)
    }
}

pub(crate) use util::dispatch_2d;

/// Maps a MAP_READ buffer whose copy has been submitted and returns its bytes once the GPU is done.
pub async fn map_read_async(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
    readback::map_and_copy(device, buffer).await
}

/// The environment variable (name, value) that keeps Mesa's Vulkan device-selection layer from probing for a
/// Wayland compositor where there can be none, or `None` where it is not needed (or already set). Each client
/// sets it its own way before the first adapter is looked for: the CLI first thing in `main`, the Python package
/// through `os.environ` when it is imported.
///
/// Every Mesa install enables that layer implicitly. When the instance has the Wayland surface extension (wgpu
/// enables every window-system extension the driver offers) the layer calls `wl_display_connect` to find the
/// GPU driving the display, and libwayland prints `error: XDG_RUNTIME_DIR is invalid or not set in the
/// environment.` twice when that variable is missing, as on servers, in containers and in CI: an alarming line
/// on every headless run although nothing is wrong. The layer only reorders adapters, and wgpu chooses among
/// them itself, so where there is no runtime directory the layer is switched off through its documented
/// `NODEVICE_SELECT` variable.
pub fn headless_vulkan_setting() -> Option<(&'static str, &'static str)> {
    let runtime_dir = std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| std::path::Path::new(&d).is_dir());
    (!runtime_dir && std::env::var_os("NODEVICE_SELECT").is_none()).then_some(("NODEVICE_SELECT", "1"))
}
