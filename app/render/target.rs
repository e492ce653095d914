//! Offscreen targets: a colour target with its own depth buffer at 4x MSAA, resolved into a texture that is read
//! back (the `render` command, tests) or shown by egui (the viewer), and [`Offscreen`] rendering to an image.

use super::camera::OrbitCamera;
use super::cubes::{CubeRenderer, DEPTH_FORMAT, Scene, Style};
use crate::gpu::{AdapterSummary, Gpu, GpuError};

/// Format of offscreen targets: sRGB, so the hardware encodes and egui can show it as a texture.
pub const TARGET_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Multisampling of offscreen targets.
pub const TARGET_SAMPLES: u32 = 4;

/// An offscreen colour target with its own depth buffer, drawn at 4x MSAA and resolved into a texture that can
/// be read back (the `render` command, tests) or shown by egui (the app).
pub struct RenderTarget {
    pub width: u32,
    pub height: u32,
    msaa: wgpu::TextureView,
    depth: wgpu::TextureView,
    resolved: wgpu::Texture,
    resolved_view: wgpu::TextureView,
    gamma_view: wgpu::TextureView,
    /// Whether the target encodes sRGB itself; otherwise the background is encoded here (as the shader encodes
    /// the cubes).
    srgb: bool,
}

impl RenderTarget {
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> RenderTarget {
        let size = wgpu::Extent3d { width: width.max(1), height: height.max(1), depth_or_array_layers: 1 };
        // The resolved texture can also be viewed as plain Rgba8Unorm: egui composites in gamma space and wants
        // the encoded bytes as they are, not decoded to linear by an sRGB view.
        let texture = |label: &str, format, samples, usage, view_formats: &[wgpu::TextureFormat]| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats,
            })
        };
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let format = target_format(device);
        let gamma_format = [wgpu::TextureFormat::Rgba8Unorm];
        let resolved = texture(
            "voxel view",
            format,
            1,
            attach | wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::TEXTURE_BINDING,
            if format == TARGET_FORMAT { &gamma_format } else { &[] },
        );
        RenderTarget {
            width: size.width,
            height: size.height,
            msaa: texture("voxel view msaa", format, TARGET_SAMPLES, attach, &[]).create_view(&Default::default()),
            depth: texture("voxel view depth", DEPTH_FORMAT, TARGET_SAMPLES, attach, &[])
                .create_view(&Default::default()),
            resolved_view: resolved.create_view(&Default::default()),
            gamma_view: resolved
                .create_view(&wgpu::TextureViewDescriptor { format: Some(gamma_format[0]), ..Default::default() }),
            resolved,
            srgb: format.is_srgb(),
        }
    }

    /// The resolved image viewed as non-sRGB Rgba8Unorm: sampling yields the sRGB-encoded values, as egui's
    /// gamma-space compositing expects of its textures.
    pub fn gamma_view(&self) -> &wgpu::TextureView {
        &self.gamma_view
    }

    /// Clears to the background and draws `scene` (if any) from `camera`.
    pub fn draw(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        renderer: &CubeRenderer,
        scene: Option<&Scene>,
        camera: &OrbitCamera,
        style: &Style,
    ) {
        if let Some(scene) = scene {
            renderer.update(queue, scene, camera, self.width as f32 / self.height as f32, style);
        }
        let bg = match self.srgb {
            true => style.background,
            false => style.background.map(encode_srgb),
        };
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("voxels"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &self.msaa,
                    depth_slice: None,
                    resolve_target: Some(&self.resolved_view),
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: bg[0] as f64,
                            g: bg[1] as f64,
                            b: bg[2] as f64,
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Discard,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &self.depth,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if let Some(scene) = scene {
                renderer.draw(&mut pass, scene, style);
            }
        }
        queue.submit([encoder.finish()]);
    }

    /// Reads the resolved image back, blocking until the GPU is done.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn read(&self, gpu: &Gpu) -> Result<image::RgbaImage, GpuError> {
        pollster::block_on(self.read_async(gpu))
    }

    /// Reads the resolved image back (rows are padded to 256 bytes in the copy).
    pub async fn read_async(&self, gpu: &Gpu) -> Result<image::RgbaImage, GpuError> {
        self.read_later(gpu).await
    }

    /// Copies the resolved image out now and returns the future of its pixels, which does not borrow the target
    /// (the app's screenshot outlives the frame that asked for it).
    pub fn read_later(
        &self,
        gpu: &Gpu,
    ) -> impl std::future::Future<Output = Result<image::RgbaImage, GpuError>> + 'static + use<> {
        let (width, height) = (self.width, self.height);
        let row = width * 4;
        let padded = row.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("image readback"),
            size: padded as u64 * height as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            self.resolved.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &readback,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(padded), rows_per_image: None },
            },
            wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        );
        gpu.queue.submit([encoder.finish()]);
        let device = gpu.device.clone();
        async move {
            let bytes = crate::gpu::map_read_async(&device, &readback).await?;
            let mut pixels = Vec::with_capacity((row * height) as usize);
            for r in 0..height as usize {
                pixels.extend_from_slice(&bytes[r * padded as usize..][..row as usize]);
            }
            image::RgbaImage::from_raw(width, height, pixels)
                .ok_or_else(|| GpuError::Device("image size mismatch".into()))
        }
    }
}

/// Headless rendering to an image.
pub struct Offscreen {
    pub renderer: CubeRenderer,
}

impl Offscreen {
    pub fn new(gpu: &Gpu) -> Offscreen {
        Offscreen { renderer: CubeRenderer::new(&gpu.device, target_format(&gpu.device), TARGET_SAMPLES) }
    }

    /// Renders `scene` from `camera` into a `width` × `height` RGBA image (see [`check_picture`] for the check
    /// a caller makes before it shows or writes it).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn render(
        &self,
        gpu: &Gpu,
        scene: &Scene,
        camera: &OrbitCamera,
        style: &Style,
        width: u32,
        height: u32,
    ) -> Result<image::RgbaImage, GpuError> {
        let target = RenderTarget::new(&gpu.device, width, height);
        target.draw(&gpu.device, &gpu.queue, &self.renderer, Some(scene), camera, style);
        target.read(gpu)
    }
}

/// The format of offscreen targets on `device`: [`TARGET_FORMAT`], or plain Rgba8Unorm (the shader encodes) on
/// wgpu's GL backend, native GL as well as WebGL2. There a texture cannot be viewed in another format: an sRGB
/// target created with an Rgba8Unorm view format (the viewer's [`RenderTarget::gamma_view`]) reads back as all
/// zeros on Mesa's llvmpipe, clear colour included (issue 65), and WebGL2 has no view formats at all.
pub fn target_format(device: &wgpu::Device) -> wgpu::TextureFormat {
    if device.adapter_info().backend == wgpu::Backend::Gl { wgpu::TextureFormat::Rgba8Unorm } else { TARGET_FORMAT }
}

/// Checks a picture read back after drawing `voxels` voxels: one in which every pixel is the same (the clear
/// colour, or nothing at all) shows none of them, which is a fault of the adapter's drawing or readback, never
/// a picture to hand to the user.
pub fn check_picture(image: &image::RgbaImage, voxels: u32, adapter: &AdapterSummary) -> Result<(), GpuError> {
    let first = image.pixels().next().copied();
    let uniform = first.is_none_or(|first| image.pixels().all(|p| *p == first));
    if voxels > 0 && uniform {
        let what = match first {
            Some(p) if p[3] == 0 => "nothing at all (every pixel transparent)".to_string(),
            Some(p) => format!("every pixel #{:02x}{:02x}{:02x}", p[0], p[1], p[2]),
            None => "no pixel".to_string(),
        };
        return Err(GpuError::BlankPicture { voxels, adapter: adapter.to_string(), what });
    }
    Ok(())
}

/// The sRGB transfer function (the shader's `encode`), for clear colours of targets that are not sRGB.
fn encode_srgb(linear: f32) -> f32 {
    if linear <= 0.003_130_8 { linear * 12.92 } else { 1.055 * linear.powf(1.0 / 2.4) - 0.055 }
}
