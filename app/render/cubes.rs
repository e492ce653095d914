//! The cube renderer: instanced cubes from the voxel list (`shaders/cubes.wgsl`), the translucent overlay of the
//! source mesh and the floor, with the [`Style`] they are drawn in and the [`Scene`] they are drawn from.

use super::camera::OrbitCamera;
use super::floor::Floor;
use super::instances::is_webgl2;
use crate::gpu::compact::Instances;
use crate::mesh::Mesh;
use crate::voxel::GridSpec;
use wgpu::util::DeviceExt;

pub const CUBES_WGSL: &str = crate::gpu::wgsl::wgsl_module!(include_str!("../../shaders/cubes.wgsl"));
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
    pub voxels: Instances,
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

/// What differs between the renderer's three pipelines.
struct Pass<'a> {
    label: &'a str,
    vs: &'a str,
    fs: &'a str,
    buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    blend: Option<wgpu::BlendState>,
    depth_write: bool,
    compare: wgpu::CompareFunction,
    cull: Option<wgpu::Face>,
}

/// The shader module, layout and target the pipelines share.
struct Target<'a> {
    module: &'a wgpu::ShaderModule,
    layout: &'a wgpu::PipelineLayout,
    format: wgpu::TextureFormat,
    samples: u32,
}

/// One pipeline of the cube shader.
fn render_pipeline(device: &wgpu::Device, target: &Target, pass: &Pass) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(pass.label),
        layout: Some(target.layout),
        vertex: wgpu::VertexState {
            module: target.module,
            entry_point: Some(pass.vs),
            compilation_options: Default::default(),
            buffers: pass.buffers,
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            front_face: wgpu::FrontFace::Ccw,
            cull_mode: pass.cull,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(pass.depth_write),
            depth_compare: Some(pass.compare),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: wgpu::MultisampleState { count: target.samples, ..Default::default() },
        fragment: Some(wgpu::FragmentState {
            module: target.module,
            entry_point: Some(pass.fs),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: target.format,
                blend: pass.blend,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// The view uniform, and on the storage path the voxel list, colours and occlusion.
fn bind_group_layout(device: &wgpu::Device, attributes: bool) -> wgpu::BindGroupLayout {
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
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("cubes"),
        entries: if attributes { &storage[..1] } else { &storage },
    })
}

/// On WebGL2, what the storage buffers carry elsewhere, per instance: the voxel (two u32), its colour (RGBA8,
/// when there are colours) and its occlusion (two u32).
const VOXEL_ATTRIBUTE: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![0 => Uint32x2];
const COLOUR_ATTRIBUTE: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![1 => Unorm8x4];
const OCCLUSION_ATTRIBUTE: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![2 => Uint32x2];
const MESH_ATTRIBUTE: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![0 => Float32x3];

fn instance_buffer(stride: u64, attributes: &[wgpu::VertexAttribute]) -> Option<wgpu::VertexBufferLayout<'_>> {
    Some(wgpu::VertexBufferLayout { array_stride: stride, step_mode: wgpu::VertexStepMode::Instance, attributes })
}

impl CubeRenderer {
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat, samples: u32) -> CubeRenderer {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("cubes.wgsl"),
            source: wgpu::ShaderSource::Wgsl(CUBES_WGSL.into()),
        });
        let attributes = is_webgl2(device);
        let layout = bind_group_layout(device, attributes);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("cubes"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let target = Target { module: &module, layout: &pipeline_layout, format, samples };
        let instances = [
            instance_buffer(8, &VOXEL_ATTRIBUTE),
            instance_buffer(4, &COLOUR_ATTRIBUTE),
            instance_buffer(8, &OCCLUSION_ATTRIBUTE),
        ];
        let mesh_vertices = [Some(wgpu::VertexBufferLayout {
            array_stride: 12,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &MESH_ATTRIBUTE,
        })];
        let cubes = Pass {
            label: "cubes",
            vs: if attributes { "vs_cube_attributes" } else { "vs_cube" },
            fs: "fs_cube",
            buffers: if attributes { &instances } else { &[] },
            blend: None,
            depth_write: true,
            compare: wgpu::CompareFunction::LessEqual,
            cull: Some(wgpu::Face::Back),
        };
        // Translucent lines behind the voxels, seen from both sides (from below it is not drawn at all).
        let floor = Pass {
            label: "floor",
            vs: "vs_floor",
            fs: "fs_floor",
            buffers: &[],
            blend: Some(wgpu::BlendState::ALPHA_BLENDING),
            depth_write: false,
            cull: None,
            ..cubes
        };
        // The surface lies inside its conservative voxel shell, so the overlay ignores depth: a translucent
        // ghost of the front faces over the voxels.
        let mesh = Pass {
            label: "mesh overlay",
            vs: "vs_mesh",
            fs: "fs_mesh",
            buffers: &mesh_vertices,
            compare: wgpu::CompareFunction::Always,
            cull: Some(wgpu::Face::Back),
            ..floor
        };
        CubeRenderer {
            cubes: render_pipeline(device, &target, &cubes),
            floor: render_pipeline(device, &target, &floor),
            mesh: render_pipeline(device, &target, &mesh),
            layout,
            encode_srgb: !format.is_srgb(),
            attributes,
        }
    }

    /// Builds the drawable scene for a voxel list in grid `spec`, with the source mesh for the overlay.
    pub fn scene(&self, device: &wgpu::Device, voxels: Instances, spec: GridSpec, mesh: Option<&Mesh>) -> Scene {
        self.coloured_scene(device, voxels, None, spec, mesh)
    }

    /// [`CubeRenderer::scene`] with a colour per instance (see [`super::coloured_instances`]).
    pub fn coloured_scene(
        &self,
        device: &wgpu::Device,
        voxels: Instances,
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

    /// `scene` with ambient occlusion per instance (from [`super::occlusion_buffer`] of the grid its instances came
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
        voxels: &Instances,
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
            grid: scene.spec.voxel_size.as_vec3().extend(0.0).to_array(),
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
