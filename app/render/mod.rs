//! The voxel renderer: instanced cubes drawn from the compacted voxel list (`shaders/cubes.wgsl`), an optional
//! translucent overlay of the source mesh, an orbit camera, and offscreen rendering to an image. It needs no
//! window: the `render` command and the tests use it headless, the app inside egui's render pass.
//!
//! One file per thing it owns: [`cubes`] (pipelines, style, scene), [`instances`] (voxels and their occlusion as
//! instances), [`scene`] (whether a scene draws the GPU's list or the grid), [`floor`], [`target`] (offscreen targets, images), [`cut`], [`slice`](mod@slice)
//! (a distance field's slice) and [`camera`].

pub mod camera;
pub mod cubes;
pub mod cut;
pub mod floor;
pub mod instances;
pub mod scene;
pub mod slice;
pub mod target;

pub use camera::OrbitCamera;
pub use cubes::{CUBES_WGSL, CubeRenderer, DEPTH_FORMAT, Scene, Style};
pub use cut::Cut;
pub use floor::Floor;
pub use instances::{ambient_occlusion, coloured_instances, instances_from_grid, is_webgl2, occlusion_buffer};
pub use scene::Showing;
pub use target::{Offscreen, RenderTarget, TARGET_FORMAT, TARGET_SAMPLES, check_picture, target_format};
