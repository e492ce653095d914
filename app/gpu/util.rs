//! Generic wgpu helpers every compute pass uses (bind group layout entries, pipelines, storage buffers, error
//! scopes, one-pipeline modules and their dispatch), so that the passes (`voxelize`, `solid`, `compact`, `colour`,
//! `distance`, `query`) depend on this module and not on each other.

use super::GpuError;

pub(crate) fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

pub(crate) fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

pub(crate) fn pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layouts: &[Option<&wgpu::BindGroupLayout>],
    entry: &str,
) -> wgpu::ComputePipeline {
    pipeline_with(device, module, layouts, entry, &[])
}

/// [`pipeline`] with values for the shader's pipeline-overridable constants.
pub(crate) fn pipeline_with(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layouts: &[Option<&wgpu::BindGroupLayout>],
    entry: &str,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(entry),
        bind_group_layouts: layouts,
        immediate_size: 0,
    });
    let _compile = crate::trace::driver_compile();
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: Some(&layout),
        module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
        cache: None,
    })
}

/// A one-pipeline compute module: `source` compiled, one bind group layout of `entries`, and the pipeline of
/// `entry` on it (the distance and query passes).
pub(crate) fn single_pipeline(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
    entry: &str,
) -> (wgpu::BindGroupLayout, wgpu::ComputePipeline) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries });
    let pipeline = pipeline(device, &module, &[Some(&layout)], entry);
    (layout, pipeline)
}

/// Binds `buffers` to bindings 0, 1, … of `layout` and submits one dispatch of `pipeline` over `groups` (x, y).
pub(crate) fn submit_dispatch(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    pipeline: (&wgpu::BindGroupLayout, &wgpu::ComputePipeline),
    buffers: &[&wgpu::Buffer],
    groups: (u32, u32),
) {
    let bound: Vec<(u32, &wgpu::Buffer)> = buffers.iter().enumerate().map(|(i, &b)| (i as u32, b)).collect();
    submit_bound(device, queue, pipeline, &bound, groups);
}

/// Binds each `(binding, buffer)` of `buffers` in `layout` and submits one dispatch of `pipeline` over `groups`
/// (x, y): for an entry point that reads some of its module's bindings.
pub(crate) fn submit_bound(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    (layout, pipeline): (&wgpu::BindGroupLayout, &wgpu::ComputePipeline),
    buffers: &[(u32, &wgpu::Buffer)],
    groups: (u32, u32),
) {
    let entries: Vec<wgpu::BindGroupEntry> =
        buffers.iter().map(|&(binding, b)| wgpu::BindGroupEntry { binding, resource: b.as_entire_binding() }).collect();
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor { label: None, layout, entries: &entries });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(groups.0, groups.1, 1);
    }
    submit(queue, encoder.finish());
}

/// Submits `commands`, timed as a wait for the device ([`crate::trace::device_wait`]): a driver may run earlier
/// work before it returns (lavapipe does), and that time is the device's, not the host's.
pub(crate) fn submit(queue: &wgpu::Queue, commands: wgpu::CommandBuffer) {
    let _wait = crate::trace::device_wait();
    queue.submit([commands]);
}

pub(crate) fn storage_buffer(device: &wgpu::Device, label: &str, size: u64, extra: wgpu::BufferUsages) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        // Zero-sized bindings are invalid; four bytes stand in for an empty array.
        size: size.max(4).next_multiple_of(4),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | extra,
        mapped_at_creation: false,
    })
}

/// Out-of-memory and validation error scopes: what they catch becomes an error instead of aborting the process.
pub(crate) struct ErrorScopes {
    oom: wgpu::ErrorScopeGuard,
    validation: wgpu::ErrorScopeGuard,
}

impl ErrorScopes {
    pub(crate) fn push(device: &wgpu::Device) -> ErrorScopes {
        let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        ErrorScopes { oom, validation }
    }

    pub(crate) async fn pop(self) -> Result<(), GpuError> {
        let v = self.validation.pop().await;
        let o = self.oom.pop().await;
        if let Some(e) = o {
            return Err(GpuError::OutOfMemory(super::describe(&e)));
        }
        if let Some(e) = v {
            return Err(GpuError::Device(super::describe(&e)));
        }
        Ok(())
    }
}

/// Runs one step of a voxelization (allocations, a submit) inside error scopes, so a failed allocation or dispatch
/// is reported where it happened.
pub(crate) async fn scoped<T>(device: &wgpu::Device, f: impl FnOnce() -> Result<T, GpuError>) -> Result<T, GpuError> {
    // In the browser every popped scope waits for the GPU process (measured: ~150-400 ms each on Chromium with
    // SwiftShader), so there one scope pair spans the whole voxelization (`voxelize_async`) instead.
    if cfg!(target_arch = "wasm32") {
        return f();
    }
    let scopes = ErrorScopes::push(device);
    let result = f();
    scopes.pop().await?;
    result
}

/// A buffer holding `contents`; four zero bytes stand in for an empty array, because zero-sized bindings are
/// invalid.
pub(crate) fn buffer_init(
    device: &wgpu::Device,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    let contents = if contents.is_empty() { &[0u8; 4][..] } else { contents };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
}

/// Splits `groups` workgroups into a 2D dispatch within the 65,535-per-dimension limit.
pub(crate) fn dispatch_2d(groups: u32) -> (u32, u32) {
    let x = groups.clamp(1, 65_535);
    (x, groups.div_ceil(x))
}
