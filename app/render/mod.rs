//! The voxel renderer: instanced cubes drawn from the compacted voxel list (`shaders/cubes.wgsl`), an optional
//! translucent overlay of the source mesh, an orbit camera, and offscreen rendering to an image. It needs no
//! window: the `render` command and the tests use it headless, the app inside egui's render pass.

pub mod camera;

use crate::gpu::compact::CompactVoxels;
use crate::gpu::{Gpu, GpuError};
use crate::mesh::Mesh;
use crate::voxel::colour::VoxelColours;
use crate::voxel::{GridSpec, VoxelGrid};
pub use camera::OrbitCamera;
use camera::UpAxis;
use wgpu::util::DeviceExt;

pub const CUBES_WGSL: &str = include_str!("../../shaders/cubes.wgsl");
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// How the scene looks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Style {
    pub show_mesh: bool,
    /// Darken the border of every cube face.
    pub edges: bool,
    /// Linear RGB of the cubes.
    pub color: [f32; 3],
    /// Draw the voxels' own colours where the scene has them (otherwise `color`).
    pub voxel_colours: bool,
    /// Darken face corners by ambient occlusion where the scene has it ([`CubeRenderer::with_occlusion`]).
    pub ao: bool,
    /// Draw a grid of lines in the plane under the model (see [`Floor`]).
    pub floor: bool,
    pub background: [f32; 3],
}

impl Default for Style {
    fn default() -> Style {
        Style {
            show_mesh: false,
            edges: true,
            color: [0.86, 0.36, 0.08],
            voxel_colours: true,
            ao: true,
            // Off for images (`render`, thumbnails); the viewer turns it on.
            floor: false,
            background: [0.018, 0.02, 0.026],
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ViewUniform {
    view_proj: [[f32; 4]; 4],
    grid: [f32; 4],
    color: [f32; 4],
    mesh_color: [f32; 4],
    options: [f32; 4],
    // The floor (see `Floor` and cubes.wgsl).
    floor_min: [f32; 4],
    floor_max: [f32; 4],
    floor_phase: [f32; 4],
}

/// GPU data of one voxelized mesh, ready to draw.
pub struct Scene {
    pub spec: GridSpec,
    pub voxels: CompactVoxels,
    /// Whether each instance has a colour (sRGB RGBA8, one u32 per instance, in the list's order).
    pub coloured: bool,
    /// The instances' colours, if any (bound as a vertex buffer on WebGL2).
    colours: Option<wgpu::Buffer>,
    /// The instances' ambient occlusion, if any (see [`ambient_occlusion`]).
    occlusion: Option<wgpu::Buffer>,
    mesh: Option<(wgpu::Buffer, u32)>,
    uniform: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl Scene {
    /// Bounds of the grid in the drawing frame, whose origin is the grid origin: scenes are drawn relative to
    /// it so a mesh far from the world origin (world = `spec.origin` + drawing position, in f64) does not lose
    /// its shape to f32 on the way to the screen.
    pub fn bounds(&self) -> (glam::Vec3, glam::Vec3) {
        (glam::Vec3::ZERO, (self.spec.dims.as_dvec3() * self.spec.voxel_size).as_vec3())
    }
}

/// The floor grid: a square of lines in the plane of the grid's lowest face along the up axis, centred under the
/// model and reaching past it, that shows which way is down and, by its spacing, how big the model is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Floor {
    /// The up axis's index (1 for Y, 2 for Z).
    pub up: usize,
    /// The square's corners in the drawing frame (relative to the grid origin); both lie in the floor's plane.
    pub min: glam::Vec3,
    pub max: glam::Vec3,
    /// Distance between lines in mesh units: a power of ten, chosen so that 4 to 40 lines cross the model.
    /// Every tenth line is brighter.
    pub spacing: f64,
    /// The world coordinates of the drawing frame's origin modulo ten spacings: lines lie where a drawing-frame
    /// coordinate plus this is a multiple of the spacing, at the same world positions wherever the grid is.
    pub phase: glam::Vec3,
}

impl Floor {
    /// The floor of grid `spec` seen with `up` up.
    pub fn new(spec: &GridSpec, up: UpAxis) -> Floor {
        let up = match up {
            UpAxis::Y => 1,
            UpAxis::Z => 2,
        };
        let size = spec.dims.as_dvec3() * spec.voxel_size;
        let (a, b) = ((up + 1) % 3, (up + 2) % 3);
        let extent = size[a].max(size[b]).max(spec.voxel_size);
        let spacing = 10f64.powf((extent / 4.0).log10().floor());
        // The square reaches 30% of the model's larger side beyond it on each side; the shader fades its rim.
        let half = 0.8 * extent;
        let (mut min, mut max) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
        for axis in [a, b] {
            let centre = 0.5 * size[axis];
            (min[axis], max[axis]) = (centre - half, centre + half);
        }
        let phase = spec.origin.map(|o| o.rem_euclid(10.0 * spacing));
        Floor { up, min: min.as_vec3(), max: max.as_vec3(), spacing, phase: phase.as_vec3() }
    }

    /// Whether `eye` (in the drawing frame) is above the floor; from below it is not drawn, as it would cover the
    /// model.
    pub fn seen_from(&self, eye: glam::Vec3) -> bool {
        eye[self.up] > self.min[self.up]
    }
}

/// Whether `device` has WebGL2's limits (`wgpu::Limits::downlevel_webgl2_defaults`), the only ones without
/// storage buffers: its vertex shaders then get the voxels as per-instance vertex attributes, and its textures
/// cannot be viewed in another format, so offscreen targets are not sRGB and the shader encodes.
pub fn is_webgl2(device: &wgpu::Device) -> bool {
    device.limits().max_storage_buffers_per_shader_stage == 0
}

/// Usage of the buffers that carry instances (voxel list, colours): read by the vertex shader as storage
/// buffers, or as vertex buffers on WebGL2.
fn instance_usage(device: &wgpu::Device) -> wgpu::BufferUsages {
    match is_webgl2(device) {
        true => wgpu::BufferUsages::VERTEX,
        false => wgpu::BufferUsages::STORAGE,
    }
}

/// The format of offscreen targets on `device`: [`TARGET_FORMAT`], or plain Rgba8Unorm on WebGL2 (see
/// [`is_webgl2`]).
pub fn target_format(device: &wgpu::Device) -> wgpu::TextureFormat {
    if is_webgl2(device) { wgpu::TextureFormat::Rgba8Unorm } else { TARGET_FORMAT }
}

/// Uploads a host grid's set voxels in the compacted layout, for grids voxelized on the CPU.
pub fn instances_from_grid(device: &wgpu::Device, grid: &VoxelGrid) -> CompactVoxels {
    let packed: Vec<u32> = grid.iter_set().flat_map(|v| [v.x | (v.y << 16), v.z]).collect();
    let count = (packed.len() / 2) as u32;
    let contents: &[u8] = if packed.is_empty() { &[0; 8] } else { bytemuck::cast_slice(&packed) };
    let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("voxel list"),
        contents,
        usage: instance_usage(device) | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
    });
    CompactVoxels { buffer, count }
}

/// Uploads the set voxels of `shown` (all of `grid`, its exposed voxels, a cut-away of it) with their colours
/// from `colours`, which belong to `grid` (one per set voxel in storage order; see [`crate::voxel::colour`]).
pub fn coloured_instances(
    device: &wgpu::Device,
    grid: &VoxelGrid,
    shown: &VoxelGrid,
    colours: &VoxelColours,
) -> (CompactVoxels, wgpu::Buffer) {
    let ranks = crate::voxel::colour::word_ranks(grid);
    let rgba: Vec<u32> = shown
        .iter_set()
        .map(|v| {
            let rank = crate::voxel::colour::voxel_rank(grid, &ranks, v);
            rank.and_then(|r| colours.rgba.get(r as usize)).map_or(0, |c| u32::from_le_bytes(*c))
        })
        .collect();
    let contents: &[u8] = if rgba.is_empty() { &[0; 4] } else { bytemuck::cast_slice(&rgba) };
    let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("voxel colours"),
        contents,
        usage: instance_usage(device),
    });
    (instances_from_grid(device, shown), buffer)
}

/// Per-corner ambient occlusion of the faces of each voxel of `shown`, in its `iter_set` order (the order
/// [`instances_from_grid`] lists them), from the voxels of `occupied` around them. A face corner looks at the
/// three cells in front of the face that touch it (two along the face's edges, one diagonal): open (3) with none
/// set, one less for each set one, and 0 when both edge cells are set (a crease), the rule of voxel editors.
/// 2 bits per corner, face `f` (axis `f / 2`, positive when `f` is odd) and corner `u + 2 v` (`u` along axis
/// `(f / 2 + 1) % 3`, `v` along `(f / 2 + 2) % 3`) at bit `(4 f + u + 2 v) * 2` of two words.
pub fn ambient_occlusion(occupied: &VoxelGrid, shown: &VoxelGrid) -> Vec<[u32; 2]> {
    use rayon::prelude::*;
    let dims = occupied.spec.dims.as_ivec3();
    let set = |p: glam::IVec3| {
        p.cmpge(glam::IVec3::ZERO).all() && p.cmplt(dims).all() && occupied.get(p.x as u32, p.y as u32, p.z as u32)
    };
    let voxels: Vec<glam::UVec3> = shown.iter_set().collect();
    voxels
        .par_iter()
        .map(|v| {
            let mut bits = 0u64;
            for f in 0..6 {
                let axis = f / 2;
                let mut front = v.as_ivec3();
                front[axis] += if f % 2 == 1 { 1 } else { -1 };
                for c in 0..4 {
                    let mut side1 = front;
                    side1[(axis + 1) % 3] += if c & 1 == 1 { 1 } else { -1 };
                    let mut side2 = front;
                    side2[(axis + 2) % 3] += if c & 2 == 2 { 1 } else { -1 };
                    let mut corner = side1;
                    corner[(axis + 2) % 3] = side2[(axis + 2) % 3];
                    let (a, b) = (set(side1), set(side2));
                    let open = if a && b { 0 } else { 3 - a as u64 - b as u64 - set(corner) as u64 };
                    bits |= open << ((4 * f + c) * 2);
                }
            }
            [bits as u32, (bits >> 32) as u32]
        })
        .collect()
}

/// Uploads [`ambient_occlusion`] for the instances of `shown`.
pub fn occlusion_buffer(device: &wgpu::Device, occupied: &VoxelGrid, shown: &VoxelGrid) -> wgpu::Buffer {
    let words = ambient_occlusion(occupied, shown);
    let contents: &[u8] = if words.is_empty() { &[0; 8] } else { bytemuck::cast_slice(&words) };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("voxel occlusion"),
        contents,
        usage: instance_usage(device),
    })
}

/// Pipelines for one target format and sample count.
pub struct CubeRenderer {
    layout: wgpu::BindGroupLayout,
    cubes: wgpu::RenderPipeline,
    floor: wgpu::RenderPipeline,
    mesh: wgpu::RenderPipeline,
    /// Whether the shader must apply the sRGB transfer function itself (non-sRGB targets such as egui's).
    encode_srgb: bool,
    /// Instances come as vertex attributes (WebGL2; see [`is_webgl2`]) rather than from storage buffers.
    attributes: bool,
}

impl CubeRenderer {
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat, samples: u32) -> CubeRenderer {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("cubes.wgsl"),
            source: wgpu::ShaderSource::Wgsl(CUBES_WGSL.into()),
        });
        let attributes = is_webgl2(device);
        let view = wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let storage = [view, storage_vertex(1), storage_vertex(2), storage_vertex(3)];
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("cubes"),
            entries: if attributes { &storage[..1] } else { &storage },
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("cubes"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let multisample = wgpu::MultisampleState { count: samples, ..Default::default() };
        let make = |label: &str,
                    vs: &str,
                    fs: &str,
                    buffers: &[Option<wgpu::VertexBufferLayout>],
                    blend,
                    depth_write,
                    compare,
                    cull| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(vs),
                    compilation_options: Default::default(),
                    buffers,
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    front_face: wgpu::FrontFace::Ccw,
                    cull_mode: cull,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(depth_write),
                    depth_compare: Some(compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample,
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fs),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState { format, blend, write_mask: wgpu::ColorWrites::ALL })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let mesh_layout = wgpu::VertexBufferLayout {
            array_stride: 12,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3],
        };
        // On WebGL2: the voxel (two u32) and its colour (RGBA8, when there are colours) per instance.
        let instance = |stride, attributes| {
            Some(wgpu::VertexBufferLayout {
                array_stride: stride,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes,
            })
        };
        let voxel_attribute = wgpu::vertex_attr_array![0 => Uint32x2];
        let colour_attribute = wgpu::vertex_attr_array![1 => Unorm8x4];
        let occlusion_attribute = wgpu::vertex_attr_array![2 => Uint32x2];
        let instances = [
            instance(8, &voxel_attribute[..]),
            instance(4, &colour_attribute[..]),
            instance(8, &occlusion_attribute[..]),
        ];
        CubeRenderer {
            cubes: make(
                "cubes",
                if attributes { "vs_cube_attributes" } else { "vs_cube" },
                "fs_cube",
                if attributes { &instances } else { &[] },
                None,
                true,
                wgpu::CompareFunction::LessEqual,
                Some(wgpu::Face::Back),
            ),
            // Translucent lines behind the voxels, seen from both sides (from below it is not drawn at all).
            floor: make(
                "floor",
                "vs_floor",
                "fs_floor",
                &[],
                Some(wgpu::BlendState::ALPHA_BLENDING),
                false,
                wgpu::CompareFunction::LessEqual,
                None,
            ),
            // The surface lies inside its conservative voxel shell, so the overlay ignores depth: a translucent
            // ghost of the front faces over the voxels.
            mesh: make(
                "mesh overlay",
                "vs_mesh",
                "fs_mesh",
                &[Some(mesh_layout)],
                Some(wgpu::BlendState::ALPHA_BLENDING),
                false,
                wgpu::CompareFunction::Always,
                Some(wgpu::Face::Back),
            ),
            layout,
            encode_srgb: !format.is_srgb(),
            attributes,
        }
    }

    /// Builds the drawable scene for a voxel list in grid `spec`, with the source mesh for the overlay.
    pub fn scene(&self, device: &wgpu::Device, voxels: CompactVoxels, spec: GridSpec, mesh: Option<&Mesh>) -> Scene {
        self.coloured_scene(device, voxels, None, spec, mesh)
    }

    /// [`CubeRenderer::scene`] with a colour per instance (see [`coloured_instances`]).
    pub fn coloured_scene(
        &self,
        device: &wgpu::Device,
        voxels: CompactVoxels,
        colours: Option<wgpu::Buffer>,
        spec: GridSpec,
        mesh: Option<&Mesh>,
    ) -> Scene {
        let coloured = colours.is_some();
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("view"),
            size: std::mem::size_of::<ViewUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = self.bind_group(device, &uniform, &voxels, colours.as_ref(), None);
        let mesh = mesh.filter(|m| !m.triangles.is_empty()).map(|m| {
            // Into the drawing frame: anchor-relative positions moved by the anchor's offset from the grid origin,
            // which is taken in f64.
            let shift = m.anchor - spec.origin;
            let local: Vec<[glam::Vec3; 3]> =
                m.triangles.iter().map(|t| t.map(|v| (shift + v.as_dvec3()).as_vec3())).collect();
            let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("mesh overlay"),
                contents: bytemuck::cast_slice(&local),
                usage: wgpu::BufferUsages::VERTEX,
            });
            (buffer, m.triangles.len() as u32 * 3)
        });
        Scene { spec, voxels, coloured, colours, occlusion: None, mesh, uniform, bind_group }
    }

    /// `scene` with ambient occlusion per instance (from [`occlusion_buffer`] of the grid its instances came
    /// from), drawn when [`Style::ao`] is on.
    pub fn with_occlusion(&self, device: &wgpu::Device, scene: Scene, occlusion: wgpu::Buffer) -> Scene {
        let bind_group =
            self.bind_group(device, &scene.uniform, &scene.voxels, scene.colours.as_ref(), Some(&occlusion));
        Scene { occlusion: Some(occlusion), bind_group, ..scene }
    }

    /// The scene's bindings: on the storage path the uniform, list, colours and occlusion (a small unread buffer
    /// standing in for absent ones); on WebGL2 the uniform only, the rest being vertex buffers.
    fn bind_group(
        &self,
        device: &wgpu::Device,
        uniform: &wgpu::Buffer,
        voxels: &CompactVoxels,
        colours: Option<&wgpu::Buffer>,
        occlusion: Option<&wgpu::Buffer>,
    ) -> wgpu::BindGroup {
        let placeholder = (!self.attributes).then(|| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("unused instance data"),
                size: 8,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        });
        let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() }];
        if let Some(placeholder) = &placeholder {
            entries.push(wgpu::BindGroupEntry { binding: 1, resource: voxels.buffer.as_entire_binding() });
            let colours = colours.unwrap_or(placeholder);
            entries.push(wgpu::BindGroupEntry { binding: 2, resource: colours.as_entire_binding() });
            let occlusion = occlusion.unwrap_or(placeholder);
            entries.push(wgpu::BindGroupEntry { binding: 3, resource: occlusion.as_entire_binding() });
        }
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("cubes"),
            layout: &self.layout,
            entries: &entries,
        })
    }

    /// Writes the camera and style for the next draw.
    pub fn update(&self, queue: &wgpu::Queue, scene: &Scene, camera: &OrbitCamera, aspect: f32, style: &Style) {
        let floor = Floor::new(&scene.spec, camera.up);
        let seen = style.floor && floor.seen_from(camera.eye());
        let u = ViewUniform {
            view_proj: camera.view_proj(aspect).to_cols_array_2d(),
            grid: [scene.spec.voxel_size as f32, 0.0, 0.0, 0.0],
            color: [style.color[0], style.color[1], style.color[2], 1.0],
            mesh_color: [0.3, 0.65, 1.0, 0.25],
            options: [
                if self.encode_srgb { 1.0 } else { 0.0 },
                if style.edges { 0.45 } else { 0.0 },
                if style.voxel_colours && scene.coloured { 1.0 } else { 0.0 },
                if style.ao && scene.occlusion.is_some() { 1.0 } else { 0.0 },
            ],
            floor_min: floor.min.extend(floor.up as f32).to_array(),
            floor_max: floor.max.extend(floor.spacing as f32).to_array(),
            floor_phase: floor.phase.extend(if seen { 1.0 } else { 0.0 }).to_array(),
        };
        queue.write_buffer(&scene.uniform, 0, bytemuck::bytes_of(&u));
    }

    /// Records the draws into a render pass whose depth attachment is [`DEPTH_FORMAT`].
    pub fn draw(&self, pass: &mut wgpu::RenderPass<'_>, scene: &Scene, style: &Style) {
        pass.set_bind_group(0, &scene.bind_group, &[]);
        if scene.voxels.count > 0 {
            pass.set_pipeline(&self.cubes);
            if self.attributes {
                // Absent colours and occlusion are not read; the list itself stands in (it is long enough:
                // two words per instance).
                let list = scene.voxels.buffer.slice(..);
                pass.set_vertex_buffer(0, list);
                pass.set_vertex_buffer(1, scene.colours.as_ref().map_or(list, |c| c.slice(..)));
                pass.set_vertex_buffer(2, scene.occlusion.as_ref().map_or(list, |o| o.slice(..)));
            }
            pass.draw(0..36, 0..scene.voxels.count);
        }
        if style.floor {
            // A camera below the floor is handled in the shader, which has the eye (`update`).
            pass.set_pipeline(&self.floor);
            pass.draw(0..6, 0..1);
        }
        if let (true, Some((buffer, vertices))) = (style.show_mesh, &scene.mesh) {
            pass.set_pipeline(&self.mesh);
            pass.set_vertex_buffer(0, buffer.slice(..));
            pass.draw(0..*vertices, 0..1);
        }
    }
}

/// The sRGB transfer function (the shader's `encode`), for clear colours of targets that are not sRGB.
fn encode_srgb(linear: f32) -> f32 {
    if linear <= 0.003_130_8 { linear * 12.92 } else { 1.055 * linear.powf(1.0 / 2.4) - 0.055 }
}

fn storage_vertex(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

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

    /// Renders `scene` from `camera` into a `width` × `height` RGBA image.
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

/// A cut-away: the voxels at or beyond `fraction` of the grid along `axis` are not drawn, so the inside of a
/// solid shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cut {
    /// 0, 1, 2 for x, y, z.
    pub axis: usize,
    /// Where the cut lies, from 0 (nothing kept) to 1 (everything kept).
    pub fraction: f32,
}

impl Cut {
    /// Parses `x:0.5` (an axis letter, a colon, a fraction from 0 to 1).
    pub fn parse(s: &str) -> Option<Cut> {
        let (axis, fraction) = s.split_once(':')?;
        let axis = ["x", "y", "z"].iter().position(|a| a.eq_ignore_ascii_case(axis.trim()))?;
        let fraction: f32 = fraction.trim().parse().ok()?;
        (0.0..=1.0).contains(&fraction).then_some(Cut { axis, fraction })
    }

    /// How many voxel layers along the axis stay.
    pub fn keep(&self, spec: &GridSpec) -> u32 {
        (self.fraction as f64 * spec.dims[self.axis] as f64).round() as u32
    }

    /// The voxels of `grid` before the cut (what a cut-away view's voxels and their occlusion come from).
    pub fn occupied(&self, grid: &VoxelGrid) -> VoxelGrid {
        grid.cut(self.axis, self.keep(&grid.spec))
    }

    /// The voxels of `grid` a cut-away view draws: those before the cut with an empty neighbour.
    pub fn apply(&self, grid: &VoxelGrid) -> VoxelGrid {
        self.occupied(grid).exposed()
    }
}
