use meshvox::formats::VoxelFormat;
use meshvox::voxel::{Mode, Resolution};
use meshvox::{Backend, Engine, Request};

pub fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mesh = meshvox::mesh::load("builtin:torus")?;
    let engine = Engine::open(Backend::Cpu)?; // Backend::Auto takes the GPU where there is one
    let result = engine.voxelize("builtin:torus", &mesh, &Request::new(Resolution::Count(32), Mode::Solid))?;
    assert_eq!(result.report.dims[0], 32); // 32 voxels along the longest axis, x for this torus
    let mut npy = std::io::Cursor::new(Vec::new()); // any Write + Seek: a file, a buffer
    result.write(VoxelFormat::Npy, &Default::default(), &mut npy)?;
    Ok(())
}
