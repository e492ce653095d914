//! What differs between the desktop window and the web page: the wgpu device eframe opens, and the window or
//! page options.

use std::sync::Arc;

/// The device eframe opens gets the adapter's storage limits (big grids) and, where the adapter has them,
/// timestamp queries (GPU times in the panel). Shared by the desktop window and the web page.
pub fn wgpu_configuration() -> egui_wgpu::WgpuConfiguration {
    let mut wgpu_options = egui_wgpu::WgpuConfiguration::default();
    if let egui_wgpu::WgpuSetup::CreateNew(create) = &mut wgpu_options.wgpu_setup {
        create.device_descriptor = Arc::new(|adapter| {
            let supported = adapter.limits();
            let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
            // WebGL2 has no storage buffers or compute. Native GL (Mesa's llvmpipe where no Vulkan driver is
            // installed, GL 4.5) has both, and the voxelizer's passes run there as on Vulkan: it gets what the
            // adapter offers, as the CLI's device does, instead of WebGL2's floor.
            let base = match adapter.get_info().backend {
                wgpu::Backend::Gl if cfg!(target_arch = "wasm32") => wgpu::Limits::downlevel_webgl2_defaults(),
                wgpu::Backend::Gl => supported.clone(),
                _ => wgpu::Limits::default(),
            };
            wgpu::DeviceDescriptor {
                label: Some("meshvox"),
                required_features: features,
                required_limits: wgpu::Limits {
                    max_texture_dimension_2d: 8192.min(supported.max_texture_dimension_2d),
                    max_storage_buffer_binding_size: supported.max_storage_buffer_binding_size,
                    max_buffer_size: supported.max_buffer_size,
                    ..base
                },
                ..Default::default()
            }
        });
    }
    wgpu_options
}

/// Native window options.
#[cfg(not(target_arch = "wasm32"))]
pub fn native_options() -> eframe::NativeOptions {
    eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([1200.0, 760.0])
            .with_title(concat!("meshvox ", env!("CARGO_PKG_VERSION"))),
        renderer: eframe::Renderer::Wgpu,
        wgpu_options: wgpu_configuration(),
        ..Default::default()
    }
}

/// Web page options: WebGPU through wgpu; in the `webgl` build (which the page loads where there is no WebGPU)
/// WebGL2 only.
#[cfg(target_arch = "wasm32")]
pub fn web_options() -> eframe::WebOptions {
    let wgpu_options = wgpu_configuration();
    #[cfg(feature = "webgl")]
    let wgpu_options = {
        let mut options = wgpu_options;
        if let egui_wgpu::WgpuSetup::CreateNew(create) = &mut options.wgpu_setup {
            create.instance_descriptor.backends = wgpu::Backends::GL;
        }
        options
    };
    eframe::WebOptions { wgpu_options, ..Default::default() }
}
