//! The voxel model as a mesh: the outer faces of the set voxels (a face between two set voxels is left out),
//! written as binary glTF (`.glb`), binary PLY, OBJ or binary STL, in world space at the source mesh's position and scale, with
//! the voxel colours as vertex colours.
//!
//! * **Faces.** Every face of a set voxel whose neighbour across it is empty or outside the grid, as a quad wound
//!   counter-clockwise seen from outside. `.glb` splits each quad into two triangles; PLY and OBJ keep quads.
//! * **Closed and manifold.** Each quad has its own four vertices (so each can carry its voxel's colour and the
//!   faces stay flat-shaded); readers weld them by position. Where the voxels meet only along an edge or at a
//!   corner (a checkerboard of four voxels around an edge), welding by position would join four faces at one
//!   edge. There, each sheet of faces through the corner gets its own vertex, pulled 1/1000 of a voxel toward
//!   the voxels it bounds, so after welding every edge joins exactly two faces (trimesh calls the result
//!   watertight) and the solids only touch in the limit.
//! * **`--merge`** joins coplanar faces of the same colour greedily into rectangles (0fps, "Meshing in a Minecraft
//!   Game", 2012): the same surface in far fewer faces, with T-junctions where rectangles of different sizes meet
//!   (closed, but no longer edge-matched, so it is not what a watertightness check accepts).
//! * **Placement.** `.glb` stores positions relative to the grid origin in f32 under a node translated to the
//!   origin (f64 in the JSON), so a model far from the origin keeps its precision; PLY (double) and OBJ (decimal
//!   text) store world coordinates.
//! * **Memory.** The unmerged faces are generated twice (count, then write) straight from the bit grid, so the
//!   writer holds no per-face data; `--merge` holds one direction's faces (8 bytes each) and one plane's mask.

use super::error::FormatError;
use crate::mesh::material::SRGB_TO_LINEAR;
use crate::voxel::colour::{VoxelColours, word_ranks};
use crate::voxel::cpu::colour::voxel_rank;
use crate::voxel::{GridSpec, VoxelGrid};
use glam::{DVec3, IVec3, UVec3};
use std::io::Write;

/// How far a vertex is pulled toward its voxels where sheets of faces meet (in voxels).
pub const SEPARATION: f64 = 1e-3;

/// The mesh formats the voxel model (and a field's level set) is written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    Glb,
    Ply,
    Obj,
    Stl,
    /// The 3D Manufacturing Format's core ([`super::threemf`]).
    ThreeMf,
}

impl MeshFormat {
    /// The file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            MeshFormat::Glb => "glb",
            MeshFormat::Ply => "ply",
            MeshFormat::Obj => "obj",
            MeshFormat::Stl => "stl",
            MeshFormat::ThreeMf => "3mf",
        }
    }

    /// Whether the format holds vertex colours (STL and 3MF's core have none).
    pub fn holds_colour(self) -> bool {
        !matches!(self, MeshFormat::Stl | MeshFormat::ThreeMf)
    }
}

/// One exposed face: its corners in grid units from the grid origin (counter-clockwise seen from outside) and the
/// colour of its voxel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quad {
    pub corners: [DVec3; 4],
    pub colour: [u8; 4],
}

/// The faces of a grid, ready to be generated (any number of times, always in the same order).
pub struct Faces<'a> {
    grid: &'a VoxelGrid,
    colours: Option<(&'a VoxelColours, Vec<u32>)>,
    merge: bool,
}

/// The flat colour of voxels without colours (the viewer's default, sRGB).
const FLAT: [u8; 4] = [239, 161, 79, 255];

impl<'a> Faces<'a> {
    pub fn new(grid: &'a VoxelGrid, colours: Option<&'a VoxelColours>, merge: bool) -> Faces<'a> {
        Faces { grid, colours: colours.map(|c| (c, word_ranks(grid))), merge }
    }

    fn set(&self, p: IVec3) -> bool {
        let d = self.grid.spec.dims.as_ivec3();
        p.cmpge(IVec3::ZERO).all() && p.cmplt(d).all() && self.grid.get(p.x as u32, p.y as u32, p.z as u32)
    }

    fn colour(&self, v: UVec3) -> [u8; 4] {
        match &self.colours {
            Some((c, ranks)) => {
                voxel_rank(self.grid, ranks, v).and_then(|r| c.rgba.get(r as usize)).copied().unwrap_or(FLAT)
            }
            None => FLAT,
        }
    }

    /// Calls `f` with every face, merged into rectangles if asked.
    pub fn for_each(&self, f: &mut dyn FnMut(&Quad)) {
        if self.merge {
            self.for_each_merged(f);
        } else {
            self.for_each_unmerged(f);
        }
    }

    fn for_each_unmerged(&self, f: &mut dyn FnMut(&Quad)) {
        for v in self.grid.iter_set() {
            let p = v.as_ivec3();
            for axis in 0..3 {
                for positive in [false, true] {
                    let mut n = p;
                    n[axis] += if positive { 1 } else { -1 };
                    if self.set(n) {
                        continue;
                    }
                    let mut corners = face_corners(p, axis, positive);
                    for c in &mut corners {
                        *c = self.separated(c.as_ivec3(), p, axis);
                    }
                    f(&Quad { corners, colour: self.colour(v) });
                }
            }
        }
    }

    /// Corner `c` of voxel `v`'s face across `axis`, pulled toward the voxels of the face's sheet when several
    /// sheets of faces meet at `c` (see the module docs).
    fn separated(&self, c: IVec3, v: IVec3, axis: usize) -> DVec3 {
        let filled = self.octants(c);
        let sheets = corner_sheets(&filled, &|a, d| self.pair_by_filled(c, &filled, a, d));
        let exact = c.as_dvec3();
        if sheets.count <= 1 {
            return exact;
        }
        // The voxel's octant around c; the face lies between it and the octant across `axis`.
        let bits = v - c + 1;
        let o = (bits.x | bits.y << 1 | bits.z << 2) as usize;
        let sheet = sheets.of_slot[slot_index(axis, o & !(1 << axis))];
        // Toward the centroid of the filled octants this sheet bounds.
        let mut sum = DVec3::ZERO;
        let mut n = 0.0;
        for (s, &id) in sheets.of_slot.iter().enumerate() {
            if id == sheet {
                let (a, low) = slot_octants(s);
                let inside = if filled[low] { low } else { low | 1 << a };
                sum += octant_offset(inside).as_dvec3() - 0.5;
                n += 1.0;
            }
        }
        exact + sum / n * SEPARATION
    }

    /// The eight voxels around corner `c`, as octants.
    fn octants(&self, c: IVec3) -> [bool; 8] {
        std::array::from_fn(|o| self.set(c - 1 + octant_offset(o)))
    }

    /// How the four faces at a checkerboard edge from corner `c` (along axis `a`, direction `d`) pair up: by filled
    /// voxel (each voxel's two faces form one sheet) when that leaves the two pairs in different sheets at one end
    /// of the edge at least, so they get different vertices there; otherwise by empty voxel (the filled voxels are
    /// joined around both ends, and the sheets follow the empty pockets instead).
    fn pair_by_filled(&self, c: IVec3, filled: &[bool; 8], a: usize, d: usize) -> bool {
        let apart = |filled: &[bool; 8], d: usize| {
            let sheets = corner_sheets(filled, &|_, _| true);
            let (b1, b2) = ((a + 1) % 3, (a + 2) % 3);
            // Paired by filled quadrant, s1(0) and s1(1) (the faces across b1) always lie in different pairs.
            let s1 = |y: usize| slot_index(b1, d << a | y << b2);
            sheets.of_slot[s1(0)] != sheets.of_slot[s1(1)]
        };
        if apart(filled, d) {
            return true;
        }
        let mut far = c;
        far[a] += if d == 1 { 1 } else { -1 };
        apart(&self.octants(far), 1 - d)
    }

    fn for_each_merged(&self, f: &mut dyn FnMut(&Quad)) {
        let d = self.grid.spec.dims;
        for axis in 0..3 {
            let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
            for positive in [false, true] {
                // This direction's faces, by plane: (b | c << 16 within the plane, colour), counting-sorted.
                let planes = d[axis] as usize;
                let mut counts = vec![0usize; planes + 1];
                let mut faces = Vec::new();
                for v in self.grid.iter_set() {
                    let mut n = v.as_ivec3();
                    n[axis] += if positive { 1 } else { -1 };
                    if !self.set(n) {
                        counts[v[axis] as usize + 1] += 1;
                        faces.push((v[axis], v[b] | v[c] << 16, u32::from_le_bytes(self.colour(v))));
                    }
                }
                for i in 0..planes {
                    counts[i + 1] += counts[i];
                }
                let mut sorted = vec![(0u32, 0u32); faces.len()];
                let mut next = counts.clone();
                for (plane, cell, colour) in faces {
                    sorted[next[plane as usize]] = (cell, colour);
                    next[plane as usize] += 1;
                }
                let (w, h) = (d[b] as usize, d[c] as usize);
                // Colour + 1 per cell of the plane (0: no face), merged and cleared as rectangles are taken.
                let mut mask = vec![0u64; w * h];
                for plane in 0..planes {
                    let cells = &sorted[counts[plane]..counts[plane + 1]];
                    for &(cell, colour) in cells {
                        mask[(cell >> 16) as usize * w + (cell & 0xffff) as usize] = colour as u64 + 1;
                    }
                    for &(cell, _) in cells {
                        let (i, j) = ((cell & 0xffff) as usize, (cell >> 16) as usize);
                        let key = mask[j * w + i];
                        if key == 0 {
                            continue;
                        }
                        // Grow along b, then along c while the whole row matches.
                        let mut wi = 1;
                        while i + wi < w && mask[j * w + i + wi] == key {
                            wi += 1;
                        }
                        let mut hj = 1;
                        while j + hj < h && (i..i + wi).all(|x| mask[(j + hj) * w + x] == key) {
                            hj += 1;
                        }
                        for y in j..j + hj {
                            mask[y * w + i..y * w + i + wi].fill(0);
                        }
                        let mut lo = IVec3::ZERO;
                        lo[axis] = plane as i32 + positive as i32;
                        lo[b] = i as i32;
                        lo[c] = j as i32;
                        let mut size_b = IVec3::ZERO;
                        size_b[b] = wi as i32;
                        let mut size_c = IVec3::ZERO;
                        size_c[c] = hj as i32;
                        let quad = [lo, lo + size_b, lo + size_b + size_c, lo + size_c];
                        let corners = if positive { quad } else { [quad[0], quad[3], quad[2], quad[1]] };
                        let colour = ((key - 1) as u32).to_le_bytes();
                        f(&Quad { corners: corners.map(|p| p.as_dvec3()), colour });
                    }
                }
            }
        }
    }
}

/// The corners of voxel `p`'s face across `axis` (on its positive side if `positive`), counter-clockwise seen
/// from outside.
fn face_corners(p: IVec3, axis: usize, positive: bool) -> [DVec3; 4] {
    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut lo = p;
    lo[axis] += positive as i32;
    let mut eb = IVec3::ZERO;
    eb[b] = 1;
    let mut ec = IVec3::ZERO;
    ec[c] = 1;
    // (b, c, axis) is right-handed, so b then c turns counter-clockwise seen from +axis.
    let quad = [lo, lo + eb, lo + eb + ec, lo + ec];
    let ordered = if positive { quad } else { [quad[0], quad[3], quad[2], quad[1]] };
    ordered.map(|q| q.as_dvec3())
}

/// Octant `o` (bit 0: x, 1: y, 2: z) around a corner `c` is the voxel `c - 1 + octant_offset(o)`.
fn octant_offset(o: usize) -> IVec3 {
    IVec3::new((o & 1) as i32, (o >> 1 & 1) as i32, (o >> 2 & 1) as i32)
}

/// The 12 face slots around a corner: slot `a * 4 + k` lies across axis `a` between the octant with bit `a`
/// clear and the one with it set, whose other two bits (axes `a + 1` and `a + 2`) are `k & 1` and `k >> 1`.
fn slot_index(a: usize, low: usize) -> usize {
    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
    a * 4 + (low >> b & 1) + 2 * (low >> c & 1)
}

/// A slot's axis and its octant with the axis bit clear.
fn slot_octants(s: usize) -> (usize, usize) {
    let (a, k) = (s / 4, s % 4);
    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
    (a, (k & 1) << b | (k >> 1) << c)
}

/// Which sheet each exposed slot around a corner belongs to, and how many sheets there are.
struct Sheets {
    of_slot: [u8; 12],
    count: u8,
}

/// Groups the exposed faces around a corner into sheets: two faces on one edge from the corner join, and at an
/// edge with four (a checkerboard), the two faces of each filled voxel join, or of each empty one, as
/// `by_filled(axis, direction)` says. Unexposed slots get 255.
fn corner_sheets(filled: &[bool; 8], by_filled: &dyn Fn(usize, usize) -> bool) -> Sheets {
    let exposed: [bool; 12] = std::array::from_fn(|s| {
        let (a, low) = slot_octants(s);
        filled[low] != filled[low | 1 << a]
    });
    let mut parent: [usize; 12] = std::array::from_fn(|i| i);
    fn find(parent: &mut [usize; 12], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut union = |x: usize, y: usize| {
        let (rx, ry) = (find(&mut parent, x), find(&mut parent, y));
        parent[rx] = ry;
    };
    for a in 0..3 {
        let (b1, b2) = ((a + 1) % 3, (a + 2) % 3);
        for d in 0..2 {
            // The four octants around the edge from the corner along ±a, as quadrants (x along b1, y along b2).
            let q = |x: usize, y: usize| d << a | x << b1 | y << b2;
            let s1 = |y: usize| slot_index(b1, q(0, y));
            let s2 = |x: usize| slot_index(b2, q(x, 0));
            // Around the edge: q00 -s1(0)- q10 -s2(1)- q11 -s1(1)- q01 -s2(0)- q00.
            let ring = [s1(0), s2(1), s1(1), s2(0)];
            let on: Vec<usize> = ring.iter().copied().filter(|&s| exposed[s]).collect();
            match on.len() {
                2 => union(on[0], on[1]),
                4 => {
                    // Each quadrant's two faces: q00 has s2(0), s1(0); q11 has s1(1), s2(1); q10 has s1(0), s2(1);
                    // q01 has s1(1), s2(0). Pairing by filled quadrant or by empty one (see `pair_by_filled`).
                    if filled[q(0, 0)] == by_filled(a, d) {
                        union(s1(0), s2(0));
                        union(s1(1), s2(1));
                    } else {
                        union(s1(0), s2(1));
                        union(s1(1), s2(0));
                    }
                }
                _ => {}
            }
        }
    }
    let mut of_slot = [255u8; 12];
    let mut roots: Vec<usize> = Vec::new();
    for s in 0..12 {
        if exposed[s] {
            let r = find(&mut parent, s);
            let id = roots.iter().position(|&x| x == r).unwrap_or_else(|| {
                roots.push(r);
                roots.len() - 1
            });
            of_slot[s] = id as u8;
        }
    }
    Sheets { of_slot, count: roots.len() as u8 }
}

/// Counts the faces and bounds their corners (in grid units).
fn survey(faces: &Faces) -> (u64, DVec3, DVec3) {
    let (mut n, mut lo, mut hi) = (0u64, DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    faces.for_each(&mut |q| {
        n += 1;
        for c in q.corners {
            lo = lo.min(c);
            hi = hi.max(c);
        }
    });
    (n, lo, hi)
}

/// Writes the voxel model of `grid` (with `colours`, if any; merged into rectangles if `merge`) as `format`; a
/// `.3mf` states `unit` (the mesh's, in metres) and names its object `name`.
pub fn write_mesh<W: Write + std::io::Seek>(
    grid: &VoxelGrid,
    colours: Option<&VoxelColours>,
    merge: bool,
    format: MeshFormat,
    (unit, name): (f64, &str),
    out: &mut W,
) -> Result<(), FormatError> {
    if format == MeshFormat::ThreeMf {
        // Unmerged: merged rectangles meet in T-junctions, which a slicer reads as cracks.
        return write_3mf_model(&Faces::new(grid, None, false), grid.spec, unit, name, out);
    }
    let faces = Faces::new(grid, colours, merge);
    // Voxels of a blended material keep their alpha where the format holds it.
    // (Alpha 0 marks a voxel without colour, not a transparent one.)
    let translucent = colours.is_some_and(|c| c.rgba.iter().any(|c| (1..255).contains(&c[3])));
    match format {
        MeshFormat::Glb => write_glb(&faces, grid.spec, colours.is_some(), translucent, out),
        MeshFormat::Ply => write_ply(&faces, grid.spec, translucent, out),
        MeshFormat::Obj => write_obj(&faces, grid.spec, out),
        MeshFormat::Stl => write_stl(&faces, grid.spec, out),
        MeshFormat::ThreeMf => unreachable!("written above"),
    }
}

/// The voxel model as one 3MF mesh: each face two triangles, corners shared by position (they are whole voxel
/// corners, so equal corners are equal numbers), so faces that meet along an edge share it as a slicer wants.
fn write_3mf_model<W: Write + std::io::Seek>(
    faces: &Faces,
    spec: GridSpec,
    unit: f64,
    name: &str,
    out: &mut W,
) -> Result<(), FormatError> {
    let mut index: std::collections::HashMap<[u64; 3], u32> = std::collections::HashMap::new();
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    faces.for_each(&mut |q| {
        let ids = q.corners.map(|c| {
            *index.entry(c.to_array().map(f64::to_bits)).or_insert_with(|| {
                vertices.push(spec.origin + c * spec.voxel_size);
                vertices.len() as u32 - 1
            })
        });
        triangles.extend([[ids[0], ids[1], ids[2]], [ids[0], ids[2], ids[3]]]);
    });
    if triangles.is_empty() {
        return Err(no_faces("3mf"));
    }
    super::threemf::write_3mf(&vertices, &triangles, unit, name, out)
}

/// Binary STL: each face as two triangles in f32 world coordinates with its normal (no colours: STL has none).
fn write_stl(faces: &Faces, spec: GridSpec, out: &mut impl Write) -> Result<(), FormatError> {
    let (quads, _, _) = survey(faces);
    if quads == 0 {
        return Err(no_faces("stl"));
    }
    let triangles = u32::try_from(quads * 2).map_err(|_| FormatError::Invalid {
        format: "stl",
        message: format!(
            "{quads} faces are more triangles than STL counts; use .ply or {}",
            crate::names::Setting::Merge
        ),
    })?;
    let mut header = [0u8; 80];
    header[..19].copy_from_slice(b"meshvox voxel model");
    out.write_all(&header)?;
    out.write_all(&triangles.to_le_bytes())?;
    let mut result = Ok(());
    faces.for_each(&mut |q| {
        if result.is_err() {
            return;
        }
        let p = q.corners.map(|c| spec.origin + c * spec.voxel_size);
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        let mut bytes = Vec::with_capacity(100);
        for tri in [[p[0], p[1], p[2]], [p[0], p[2], p[3]]] {
            for v in [n, tri[0], tri[1], tri[2]] {
                for x in v.as_vec3().to_array() {
                    bytes.extend_from_slice(&x.to_le_bytes());
                }
            }
            bytes.extend_from_slice(&[0, 0]);
        }
        result = out.write_all(&bytes);
    });
    result?;
    Ok(())
}

fn no_faces(format: &'static str) -> FormatError {
    FormatError::Invalid { format, message: "the grid has no set voxels, so there is no surface to write".into() }
}

fn write_glb(
    faces: &Faces,
    spec: GridSpec,
    coloured: bool,
    translucent: bool,
    out: &mut impl Write,
) -> Result<(), FormatError> {
    let (quads, lo, hi) = survey(faces);
    if quads == 0 {
        return Err(no_faces("glb"));
    }
    if quads * 4 > u32::MAX as u64 {
        return Err(FormatError::Invalid {
            format: "glb",
            message: format!("{quads} faces are more than 32-bit indices reach"),
        });
    }
    let layout = GlbLayout { quads, coloured, translucent, h: spec.voxel_size };
    let text = glb_json(&layout, spec, lo, hi);
    write_glb_head(&text, layout.bin_len(), &format!("use .ply or {}", crate::names::Setting::Merge), out)?;
    write_glb_vertices(faces, &layout, out)?;
    for i in 0..quads as u32 {
        let b = 4 * i;
        for x in [b, b + 1, b + 2, b, b + 2, b + 3] {
            out.write_all(&x.to_le_bytes())?;
        }
    }
    Ok(())
}

/// A GLB's header, its JSON chunk (`text`, padded to 4 bytes) and its binary chunk's header (`bin_len` bytes to
/// follow); refused past the format's 4 GiB, with `instead` saying what to write.
pub(super) fn write_glb_head(
    text: &[u8],
    bin_len: u64,
    instead: &str,
    out: &mut impl Write,
) -> Result<(), FormatError> {
    let total = 12 + 8 + text.len() as u64 + 8 + bin_len;
    let total = u32::try_from(total).map_err(|_| FormatError::Invalid {
        format: "glb",
        message: format!("{total} bytes is more than a GLB holds (4 GiB); {instead}"),
    })?;
    out.write_all(b"glTF")?;
    out.write_all(&2u32.to_le_bytes())?;
    out.write_all(&total.to_le_bytes())?;
    out.write_all(&(text.len() as u32).to_le_bytes())?;
    out.write_all(b"JSON")?;
    out.write_all(text)?;
    out.write_all(&(bin_len as u32).to_le_bytes())?;
    out.write_all(b"BIN\0")?;
    Ok(())
}

/// The sizes of a GLB's binary chunk: four vertices (position, and colour when coloured) and six indices a quad.
struct GlbLayout {
    quads: u64,
    coloured: bool,
    /// Some colour's alpha is below 255 (a blended material's): the material blends.
    translucent: bool,
    /// The voxel sizes: positions are in voxels until scaled by them.
    h: DVec3,
}

impl GlbLayout {
    fn stride(&self) -> u64 {
        if self.coloured { 20 } else { 12 }
    }

    fn vertex_bytes(&self) -> u64 {
        self.quads * 4 * self.stride()
    }

    fn index_bytes(&self) -> u64 {
        self.quads * 6 * 4
    }

    fn bin_len(&self) -> u64 {
        self.vertex_bytes() + self.index_bytes()
    }

    /// A corner in the node's frame (relative to the grid origin), as glTF's f32.
    fn position(&self, v: DVec3) -> [f32; 3] {
        (v * self.h).as_vec3().to_array()
    }
}

/// The GLB's JSON chunk, padded with spaces to a multiple of four bytes: one node at the grid origin (in f64;
/// positions are relative to it), one mesh, its accessors into the binary chunk, and a material for plain models.
fn glb_json(layout: &GlbLayout, spec: GridSpec, lo: DVec3, hi: DVec3) -> Vec<u8> {
    let (vertices, indices) = (layout.quads * 4, layout.quads * 6);
    let mut attributes = serde_json::json!({ "POSITION": 0 });
    let mut accessors = vec![serde_json::json!({
        "bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": vertices, "type": "VEC3",
        "min": layout.position(lo), "max": layout.position(hi),
    })];
    if layout.coloured {
        attributes["COLOR_0"] = 1.into();
        accessors.push(serde_json::json!({
            "bufferView": 0, "byteOffset": 12, "componentType": 5123, "normalized": true, "count": vertices,
            "type": "VEC4",
        }));
    }
    accessors.push(serde_json::json!({ "bufferView": 1, "componentType": 5125, "count": indices, "type": "SCALAR" }));
    let mut primitive = serde_json::json!({ "attributes": attributes, "indices": accessors.len() - 1 });
    // Coloured models use glTF's default material (white, so the vertex colours show as they are); plain ones a
    // material in the viewer's flat colour.
    let mut materials = Vec::new();
    if layout.translucent {
        primitive["material"] = 0.into();
        materials.push(serde_json::json!({ "name": "voxels", "alphaMode": "BLEND", "pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0 } }));
    } else if !layout.coloured {
        primitive["material"] = 0.into();
        materials.push(serde_json::json!({ "name": "voxels", "pbrMetallicRoughness": {
            "baseColorFactor": [0.86, 0.36, 0.08, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0 } }));
    }
    let (vertex_bytes, index_bytes) = (layout.vertex_bytes(), layout.index_bytes());
    let json = serde_json::json!({
        "asset": { "version": "2.0", "generator": "meshvox" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        // The origin in f64: positions are relative to it.
        "nodes": [{ "mesh": 0, "name": "voxels", "translation": spec.origin.to_array() }],
        "meshes": [{ "name": "voxels", "primitives": [primitive] }],
        "materials": materials,
        "buffers": [{ "byteLength": layout.bin_len() }],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": vertex_bytes, "byteStride": layout.stride(), "target": 34962 },
            { "buffer": 0, "byteOffset": vertex_bytes, "byteLength": index_bytes, "target": 34963 },
        ],
        "accessors": accessors,
    });
    let mut text = json.to_string().into_bytes();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    text
}

/// The vertices of every quad: positions, and with colours their linear RGBA as 16-bit so dark shades keep their
/// steps.
fn write_glb_vertices(faces: &Faces, layout: &GlbLayout, out: &mut impl Write) -> Result<(), FormatError> {
    let lut = &*SRGB_TO_LINEAR;
    let mut result = Ok(());
    faces.for_each(&mut |q| {
        if result.is_err() {
            return;
        }
        let c = q.colour;
        let linear = [lut[c[0] as usize], lut[c[1] as usize], lut[c[2] as usize], c[3] as f32 / 255.0]
            .map(|x| (x * 65535.0).round() as u16);
        for corner in q.corners {
            let mut bytes = Vec::with_capacity(20);
            for x in layout.position(corner) {
                bytes.extend_from_slice(&x.to_le_bytes());
            }
            if layout.coloured {
                for x in linear {
                    bytes.extend_from_slice(&x.to_le_bytes());
                }
            }
            result = out.write_all(&bytes);
        }
    });
    Ok(result?)
}

fn write_ply(faces: &Faces, spec: GridSpec, translucent: bool, out: &mut impl Write) -> Result<(), FormatError> {
    let (quads, _, _) = survey(faces);
    if quads == 0 {
        return Err(no_faces("ply"));
    }
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment {}\n\
         element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n{}\
         element face {quads}\nproperty list uchar uint vertex_indices\nend_header\n",
        model_comment(&spec),
        quads * 4,
        if translucent { "property uchar alpha\n" } else { "" },
    )?;
    let mut result = Ok(());
    faces.for_each(&mut |q| {
        for corner in q.corners {
            if result.is_err() {
                return;
            }
            let p = spec.origin + corner * spec.voxel_size;
            let mut bytes = Vec::with_capacity(27);
            for x in p.to_array() {
                bytes.extend_from_slice(&x.to_le_bytes());
            }
            bytes.extend_from_slice(&q.colour[..if translucent { 4 } else { 3 }]);
            result = out.write_all(&bytes);
        }
    });
    result?;
    for i in 0..quads as u32 {
        let b = 4 * i;
        out.write_all(&[4])?;
        for x in [b, b + 1, b + 2, b + 3] {
            out.write_all(&x.to_le_bytes())?;
        }
    }
    Ok(())
}

/// The line PLY and OBJ files of a voxel model start with: its grid, voxel size and origin.
fn model_comment(spec: &GridSpec) -> String {
    let (d, o) = (spec.dims, spec.origin);
    let h = crate::voxel::VoxelSize::from(spec.voxel_size);
    format!("meshvox voxel model: {}x{}x{} voxels of {h}, origin {} {} {}", d.x, d.y, d.z, o.x, o.y, o.z)
}

fn write_obj(faces: &Faces, spec: GridSpec, out: &mut impl Write) -> Result<(), FormatError> {
    writeln!(out, "# {}\n# v x y z r g b (sRGB colours in 0..1)", model_comment(&spec))?;
    let mut result = Ok(());
    let mut n = 0u64;
    faces.for_each(&mut |q| {
        if result.is_err() {
            return;
        }
        let c = q.colour.map(|x| x as f64 / 255.0);
        let mut text = String::new();
        for corner in q.corners {
            let p = spec.origin + corner * spec.voxel_size;
            text.push_str(&format!("v {} {} {} {:.4} {:.4} {:.4}\n", p.x, p.y, p.z, c[0], c[1], c[2]));
        }
        text.push_str(&format!("f {} {} {} {}\n", 4 * n + 1, 4 * n + 2, 4 * n + 3, 4 * n + 4));
        n += 1;
        result = out.write_all(text.as_bytes());
    });
    result?;
    if n == 0 {
        return Err(no_faces("obj"));
    }
    Ok(())
}
