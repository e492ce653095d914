//! `.vox`: MagicaVoxel through dot_vox. MagicaVoxel is Z-up while meshes are usually Y-up, so voxel `(x, y, z)` is
//! stored at `(x, dims_z - 1 - z, y)` (a proper rotation, no mirroring). Models are at most 256 voxels a side; a
//! larger grid is split into chunks, each a model placed by a transform node under one group, so it opens as one
//! object. The grid is centred on MagicaVoxel's origin.

use super::error::{FormatError, invalid};
use super::palette::Quantized;
use crate::formats::swatches::Swatches;
use crate::voxel::colour::VoxelColours;
use crate::voxel::{GridSpec, VoxelGrid};
use glam::{DVec3, UVec3};
use std::io::Write;

/// How far from its origin MagicaVoxel places and edits voxels: positions -1000 to 999 on each axis (its world is
/// 2000 a side; ephtracy/voxel-model #66, FileToVox #45). The grid is centred on the origin, so a side of up to
/// 2000 voxels is all there.
pub const VOX_WORLD: u32 = 2000;

/// What MagicaVoxel will not show of a grid of `dims` (meshvox's axes), in words, or `None` when it shows all.
pub fn beyond_the_editor(dims: UVec3) -> Option<String> {
    (dims.max_element() > VOX_WORLD).then(|| {
        format!(
            "MagicaVoxel places voxels within {} of its origin and this {}x{}x{} model reaches past it: the .vox \
             holds every voxel (vengi, Blender's and other importers read it whole), MagicaVoxel shows the middle \
             {VOX_WORLD} a side",
            VOX_WORLD / 2,
            dims.x,
            dims.y,
            dims.z
        )
    })
}

/// MagicaVoxel's limit on a model's size along each axis.
pub const VOX_MODEL_MAX: u32 = 256;

/// Our voxel `(x, y, z)` in MagicaVoxel's Z-up frame, and back.
fn to_vox(v: UVec3, dims: UVec3) -> UVec3 {
    UVec3::new(v.x, dims.z - 1 - v.z, v.y)
}

/// Writes a MagicaVoxel `.vox` file, split into models of at most 256³ (see the module documentation), every
/// voxel in one colour.
pub fn write_vox(grid: &VoxelGrid, out: &mut impl Write) -> Result<(), FormatError> {
    write_vox_coloured(grid, None, out)
}

/// [`write_vox`] with per-voxel colours, quantized to a palette of at most 255 entries
/// ([`super::palette::quantize`]).
pub fn write_vox_coloured(
    grid: &VoxelGrid,
    colours: Option<&VoxelColours>,
    out: &mut impl Write,
) -> Result<(), FormatError> {
    let quantized = colours.map(|c| super::palette::quantize(&c.rgba, 255));
    write_vox_indexed(grid, quantized.as_ref(), out)
}

/// [`write_vox`] in a fixed palette: its colours are the file's, entry `i` at colour index `i + 1` (so a `.vox`
/// file's palette keeps its slots), and each voxel takes the entry nearest its colour ([`Swatches::assign`],
/// dithered on request), the first without colours. A palette holds at most 255 colours.
pub fn write_vox_fixed(
    grid: &VoxelGrid,
    colours: Option<&VoxelColours>,
    palette: &Swatches,
    dither: bool,
    out: &mut impl Write,
) -> Result<(), FormatError> {
    if palette.colours.len() > 255 {
        return Err(FormatError::TooLarge(format!(
            "a .vox palette holds at most 255 colours; this one has {}",
            palette.colours.len()
        )));
    }
    let index = palette.assign(grid, colours, dither).into_iter().map(|e| e as u8).collect();
    let palette = palette.colours.iter().map(|c| [c[0], c[1], c[2], 255]).collect();
    write_vox_indexed(grid, Some(&Quantized { palette, index }), out)
}

/// Writes the `.vox` file, set voxel `n` in colour `quantized.index[n]` of `quantized.palette` (or every voxel
/// in one colour).
fn write_vox_indexed(grid: &VoxelGrid, quantized: Option<&Quantized>, out: &mut impl Write) -> Result<(), FormatError> {
    use dot_vox::{Dict, DotVoxData, Frame, Model, SceneNode, ShapeModel, Size, Voxel};
    let d = grid.spec.dims;
    let vd = UVec3::new(d.x, d.z, d.y);
    let chunks = (vd + VOX_MODEL_MAX - 1) / VOX_MODEL_MAX;
    let chunk_index = |c: UVec3| (c.x + chunks.x * (c.y + chunks.y * c.z)) as usize;
    let mut models: Vec<Model> = (0..chunks.z)
        .flat_map(|z| (0..chunks.y).flat_map(move |y| (0..chunks.x).map(move |x| UVec3::new(x, y, z))))
        .map(|c| {
            let size = (vd - c * VOX_MODEL_MAX).min(UVec3::splat(VOX_MODEL_MAX));
            Model { size: Size { x: size.x, y: size.y, z: size.z }, voxels: Vec::new() }
        })
        .collect();
    for (n, v) in grid.iter_set().enumerate() {
        let p = to_vox(v, d);
        let c = p / VOX_MODEL_MAX;
        let l = p % VOX_MODEL_MAX;
        let i = quantized.and_then(|q| q.index.get(n).copied()).unwrap_or(0);
        models[chunk_index(c)].voxels.push(Voxel { x: l.x as u8, y: l.y as u8, z: l.z as u8, i });
    }

    // Scene graph: root transform -> group -> (transform -> shape) per model.
    let mut scenes = vec![
        SceneNode::Transform { attributes: Dict::new(), frames: vec![Frame::default()], child: 1, layer_id: u32::MAX },
        SceneNode::Group { attributes: Dict::new(), children: Vec::new() },
    ];
    let mut children = Vec::new();
    for (id, model) in models.iter().enumerate() {
        let c = UVec3::new(id as u32 % chunks.x, id as u32 / chunks.x % chunks.y, id as u32 / (chunks.x * chunks.y));
        let size = UVec3::new(model.size.x, model.size.y, model.size.z);
        // MagicaVoxel puts a model's voxel v at t + v - size / 2; centre the whole grid on the origin.
        let t = (c * VOX_MODEL_MAX + size / 2).as_ivec3() - (vd / 2).as_ivec3();
        let mut frame = Dict::new();
        frame.insert("_t".into(), format!("{} {} {}", t.x, t.y, t.z));
        let mut attributes = Dict::new();
        attributes.insert("_name".into(), format!("meshvox {} {} {}", c.x, c.y, c.z));
        children.push(scenes.len() as u32);
        let shape = scenes.len() as u32 + 1;
        scenes.push(SceneNode::Transform { attributes, frames: vec![Frame::new(frame)], child: shape, layer_id: 0 });
        scenes.push(SceneNode::Shape {
            attributes: Dict::new(),
            models: vec![ShapeModel { model_id: id as u32, attributes: Dict::new() }],
        });
    }
    scenes[1] = SceneNode::Group { attributes: Dict::new(), children };

    let mut palette = dot_vox::DEFAULT_PALETTE.clone();
    let mut materials = Vec::new();
    match quantized {
        Some(q) => {
            for (slot, c) in palette.iter_mut().zip(&q.palette) {
                *slot = dot_vox::Color { r: c[0], g: c[1], b: c[2], a: c[3] };
            }
            materials = blend_materials(&q.palette);
        }
        // Without colours palette entry 0 is the one every voxel uses: a warm orange that reads well on
        // MagicaVoxel's grey.
        None => palette[0] = dot_vox::Color { r: 235, g: 140, b: 52, a: 255 },
    }
    let data = DotVoxData {
        version: 150,
        index_map: dot_vox::DEFAULT_INDEX_MAP.to_vec(),
        models,
        palette,
        materials,
        scenes,
        layers: dot_vox::placeholder::LAYERS.to_vec(),
    };
    data.write_vox(out)?;
    Ok(())
}

/// A `MATL` for each palette entry whose alpha is below 255 (a blended material's voxels): MagicaVoxel's blend
/// material with that opacity as `_alpha` (dot_vox's reading: the voxel blended over what is behind it). Material
/// ids are the file's colour indices, one above the palette's.
fn blend_materials(palette: &[[u8; 4]]) -> Vec<dot_vox::Material> {
    palette
        .iter()
        .enumerate()
        .filter(|(_, c)| c[3] < 255)
        .map(|(i, c)| {
            let mut properties = dot_vox::Dict::new();
            properties.insert("_type".into(), "_blend".into());
            properties.insert("_alpha".into(), format!("{}", f32::from(c[3]) / 255.0));
            dot_vox::Material { id: i as u32 + 1, properties }
        })
        .collect()
}

/// Reads a `.vox` file (one model or several placed by transform nodes) back into our orientation. Origin 0
/// and voxel size 1, since the format carries no placement.
pub fn read_vox(bytes: &[u8]) -> Result<VoxelGrid, FormatError> {
    use dot_vox::SceneNode;
    const F: &str = "vox";
    let data = dot_vox::load_bytes(bytes).map_err(|e| invalid(F, e))?;
    // Offset of each model in MagicaVoxel space, from the transform node above its shape.
    let mut placed: Vec<(usize, glam::IVec3)> = Vec::new();
    for node in &data.scenes {
        if let SceneNode::Transform { frames, child, .. } = node
            && let Some(SceneNode::Shape { models, .. }) = data.scenes.get(*child as usize)
        {
            let p = frames
                .first()
                .and_then(|f| f.position())
                .map_or(glam::IVec3::ZERO, |p| glam::IVec3::new(p.x, p.y, p.z));
            for m in models {
                let model =
                    data.models.get(m.model_id as usize).ok_or_else(|| invalid(F, "shape names a missing model"))?;
                let size = UVec3::new(model.size.x, model.size.y, model.size.z);
                placed.push((m.model_id as usize, p - (size / 2).as_ivec3()));
            }
        }
    }
    if placed.is_empty() {
        placed = (0..data.models.len()).map(|i| (i, glam::IVec3::ZERO)).collect();
    }
    let size_of = |i: usize| {
        let s = &data.models[i].size;
        UVec3::new(s.x, s.y, s.z).as_ivec3()
    };
    let lo = placed.iter().map(|&(_, o)| o).reduce(|a, b| a.min(b)).ok_or_else(|| invalid(F, "no models"))?;
    let hi = placed.iter().map(|&(i, o)| o + size_of(i)).reduce(|a, b| a.max(b)).unwrap_or(lo);
    let vd = (hi - lo).as_uvec3();
    let dims = UVec3::new(vd.x, vd.z, vd.y);
    let spec = GridSpec { origin: DVec3::ZERO, voxel_size: DVec3::ONE, dims };
    let mut grid = VoxelGrid::new(spec).map_err(|e| invalid(F, e.to_string()))?;
    for (i, o) in placed {
        for v in &data.models[i].voxels {
            let p = (o - lo + glam::IVec3::new(v.x as i32, v.y as i32, v.z as i32)).as_uvec3();
            if p.cmpge(vd).any() {
                return Err(invalid(F, "a voxel lies outside its model"));
            }
            // Inverse of to_vox.
            grid.set(p.x, p.z, dims.z - 1 - p.y);
        }
    }
    Ok(grid)
}
