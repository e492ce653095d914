//! What to voxelize: the client's [`Request`], and the [`Job`] planned from it against a mesh. Planning lays the
//! grid over the mesh, picks dense or sparse, sums the surface area and checks the memory budget once, before
//! anything large is allocated; the cost model ([`super::cost`]), [`Engine::open_for`](super::Engine::open_for)
//! and the run all read the job instead of working any of it out again.

use super::{EngineError, budget};
use crate::formats::VoxelFormat;
use crate::mesh::UpAxis;
use crate::mesh::{Aabb, Mesh};
use crate::names::Setting;
use crate::voxel::distance::{Band, MAX_BAND};
use crate::voxel::labels::AttributeSet;
use crate::voxel::voids::DrainPlan;
use crate::voxel::{Axis, GridError, GridKind, GridSpec, Length, MAX_DIM, Mode, Resolution};
use glam::DVec3;
use std::sync::atomic::{AtomicBool, Ordering};

/// What to voxelize, and within which limits: what a client asks for, in the library's words. Each client (the
/// CLI, Python, the viewer, bench) builds one in one place.
#[derive(Clone, Copy)]
pub struct Request<'a> {
    pub resolution: Resolution,
    pub axis: Axis,
    pub mode: Mode,
    /// Colour the voxels from the mesh's materials: `None` when the mesh has any colour, `Some(false)` never
    /// (`Some(true)` on a mesh without colour leaves the voxels uncoloured, as `None` does).
    pub colour: Option<bool>,
    /// Host memory the request may use; `None`: four fifths of what is available ([`crate::memory`]).
    pub max_memory: Option<u64>,
    /// The format the grid will be written in, whose writer's memory the budget counts.
    pub format: Option<VoxelFormat>,
    /// Dense or sparse grid, or `Auto`: sparse for a sparse format or where the dense grid does not fit the
    /// budget ([`Job::plan`]).
    pub grid: GridKind,
    /// Also list the exposed voxels on the GPU, for drawing them as instances on the engine's device
    /// ([`super::Voxelized::instances`]; nothing where the CPU voxelizes).
    pub instances: bool,
    /// Called now and then with (triangles done, triangles) while the CPU voxelizes, from worker threads.
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
    /// Set to stop the request: checked before voxelizing and before colouring, and per triangle by the CPU
    /// voxelizer (a GPU submission runs to its end).
    pub cancel: Option<&'a AtomicBool>,
    /// The world box the grid covers instead of the mesh's bounds, so that a dataset shares one frame; triangles
    /// outside it are clipped.
    pub bounds: Option<Aabb>,
    /// `Mode::Sdf`/`Mode::Udf`: how far from the surface distances are computed.
    pub band: Band,
    /// Per-voxel labels to make ([`crate::voxel::labels`]): on dense and sparse grids, written in `.npy` (beside
    /// a dense grid), `.npz` and `.vdb`.
    pub attributes: AttributeSet,
    /// `Mode::Sdf`/`Mode::Udf` written as a mesh: the level set's value, world units (the band is widened to hold
    /// it).
    pub level: f64,
    /// `Mode::Shell`: the shell's thickness (the band is set to hold it).
    pub thickness: Length,
    /// The mesh's unit in metres, for lengths given in metres; `None`: the format's ([`Mesh::guess_unit`]).
    pub unit: Option<f64>,
    /// The model's up axis, which drain holes go down; `None`: the format's ([`Mesh::guess_up`]).
    pub up: Option<UpAxis>,
    /// `Mode::Shell`/`Mode::Solid`: drain holes to cut ([`crate::voxel::voids`]).
    pub drain: &'a DrainPlan,
    /// `Mode::Shell`/`Mode::Solid`: set the voxels of the voids left sealed.
    pub fill_pockets: bool,
}

impl Request<'_> {
    /// A request for `resolution` voxels along the longest axis, in `mode`, with every other setting as default.
    pub fn new(resolution: Resolution, mode: Mode) -> Request<'static> {
        Request {
            resolution,
            axis: Axis::Longest,
            mode,
            colour: None,
            max_memory: None,
            format: None,
            grid: GridKind::Auto,
            instances: false,
            progress: None,
            cancel: None,
            bounds: None,
            band: Band::default(),
            attributes: AttributeSet::NONE,
            level: 0.0,
            thickness: Length::Voxels(1.0),
            unit: None,
            up: None,
            drain: &DrainPlan::None,
            fill_pockets: false,
        }
    }

    pub(super) fn cancelled(&self) -> Result<(), EngineError> {
        match self.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            true => Err(EngineError::Cancelled),
            false => Ok(()),
        }
    }
}

/// A request planned against its mesh: everything the run, the cost model and the budget need, worked out once.
#[derive(Clone, Copy)]
pub struct Job<'a> {
    /// The mesh as the user named it, for messages and the report.
    pub name: &'a str,
    pub mesh: &'a Mesh,
    pub request: Request<'a>,
    /// The world box the grid covers (what the resolution divides).
    pub bounds: Aabb,
    pub spec: GridSpec,
    /// Leaves and tiles instead of the dense bit grid.
    pub sparse: bool,
    /// The mesh's surface area in world units².
    pub area: f64,
    /// `Mode::Shell`: its thickness in voxels.
    pub thickness: f32,
    /// The mesh's unit in metres.
    pub unit: f64,
}

impl<'a> Job<'a> {
    /// Lays the grid over `mesh` as `request` asks, picks dense or sparse, and checks the memory it needs, before
    /// anything large is allocated. `name` is the mesh as the user named it, for messages.
    ///
    /// `GridKind::Auto` is sparse when the output format is (`.vdb`, `.npz`) or when the dense grid would not fit
    /// the budget and a sparse one would; a dense format past the budget is refused, pointing at the sparse
    /// formats. Colours are made on dense grids, so `Auto` keeps a coloured request dense wherever that fits.
    pub fn plan(name: &'a str, mesh: &'a Mesh, request: &Request<'a>) -> Result<Job<'a>, EngineError> {
        let grid_error = |error, sparse| EngineError::Grid { mesh: name.to_string(), error, sparse };
        let mesh_bounds = mesh.bounds().ok_or_else(|| EngineError::Empty { mesh: name.to_string() })?;
        let bounds = match request.bounds {
            Some(b) if b.min.is_finite() && b.max.is_finite() && b.min.cmplt(b.max).all() => b,
            Some(b) => return Err(EngineError::Bounds { min: b.min.to_array(), max: b.max.to_array() }),
            None => mesh_bounds,
        };
        let unit = request.unit.unwrap_or_else(|| mesh.guess_unit());
        let resolution = request.resolution.in_mesh_units(unit);
        let mut spec = GridSpec::fit(bounds, resolution, request.axis).map_err(|e| grid_error(e, false))?;
        Job::check_anisotropic(request, &spec)?;
        let format = request.format;
        let field_mesh = budget::writes_level_set(request.mode, format);
        if field_mesh && request.level > 0.0 && request.bounds.is_none() {
            // A level set above 0 lies outside the mesh, up to the level away: the grid grows by it and two voxels
            // on every side (the voxel size stays the mesh's), so the surface is not cut by the grid's boundary.
            let pad = (request.level / spec.edge()).ceil().min(f64::from(MAX_DIM)) as u32 + 2;
            spec.origin -= DVec3::splat(f64::from(pad)) * spec.voxel_size;
            spec.dims += 2 * pad;
        }
        // The grid's size is known now: a format that cannot hold it refuses it before anything is voxelized.
        if let Some(format) = format {
            format.check_fits(&spec).map_err(EngineError::TooLargeForFormat)?;
        }
        let sparse_format = format.is_some_and(VoxelFormat::is_sparse);
        let mut request = *request;
        let thickness = request.thickness.in_voxels(&spec, unit) as f32;
        if request.mode == Mode::Shell {
            request.band = Job::shell_band(thickness)?;
        }
        let voids_asked = *request.drain != DrainPlan::None || request.fill_pockets;
        if voids_asked && !matches!(request.mode, Mode::Shell | Mode::Solid) {
            return Err(EngineError::Voids(format!(
                "{} and {} are for the voids of a shell or a solid: use them with {} or {}",
                Setting::Drain,
                Setting::FillPockets,
                Setting::Mode.with("shell"),
                Setting::Mode.with("solid")
            )));
        }
        if request.mode.is_field() {
            match format {
                None => {}
                Some(f) if f.holds_field() => {}
                Some(f) if f.is_mesh() => request.band = Job::level_band(&request, &spec)?,
                Some(f) => {
                    return Err(EngineError::FieldFormat { mode: request.mode.name(), extension: f.extension() });
                }
            }
            if request.band == Band::Full && (sparse_format || request.grid == GridKind::Sparse) {
                return Err(EngineError::FullBandSparse);
            }
        }
        if mesh.points.is_some() {
            let what = match (request.mode, request.attributes.is_empty()) {
                (Mode::Surface, true) => None,
                (Mode::Surface, false) => Some(Setting::Attributes.to_string()),
                (mode, _) => Some(Setting::Mode.with(mode).to_string()),
            };
            if let Some(what) = what {
                return Err(EngineError::PointCloud { mesh: name.to_string(), what });
            }
        }
        let labelled = !request.attributes.is_empty();
        if labelled && let Some(f) = format.filter(|f| !f.holds_labels()) {
            return Err(EngineError::LabelsFormat { extension: f.extension() });
        }
        let coloured = request.colour != Some(false) && mesh.has_colour();
        let sparse = match request.grid {
            GridKind::Dense => false,
            GridKind::Sparse => true,
            // A field's level set comes from its band's leaves: its sign grid need not be dense either.
            GridKind::Auto => (sparse_format || field_mesh) && !coloured,
        };
        let area = budget::surface_area(mesh);
        let mut job = Job { name, mesh, request, bounds, spec, sparse, area, thickness, unit };
        let Some(limit) = request.max_memory.or_else(crate::memory::default_budget) else { return Ok(job) };
        let dense_fits = job.check_budget(None, limit).is_ok();
        if request.grid == GridKind::Auto && !sparse && !dense_fits && format.is_none_or(VoxelFormat::is_sparse) {
            // Over the budget dense (coloured or not), with no dense format asked for: sparse, if that fits.
            job.sparse = true;
        }
        // The area counts where a sparse estimate or a field is made.
        let area = (job.sparse || request.mode.needs_field()).then_some(area);
        job.check_budget(area, limit).map_err(|e| grid_error(e, job.sparse))?;
        Ok(job)
    }

    /// The grid's memory against `limit` bytes ([`budget::check`]): sparse for a surface of `area` when given.
    fn check_budget(&self, area: Option<f64>, limit: u64) -> Result<budget::Estimate, GridError> {
        let (r, triangles) = (&self.request, self.triangles());
        let labels = r.attributes.len();
        let level_mesh = budget::writes_level_set(r.mode, r.format);
        let estimate = |spec: &GridSpec| {
            let e = budget::estimate(spec, r.mode, r.band, r.format, triangles, area);
            let labels = budget::labels_bytes(spec, r.mode, labels, self.area, triangles);
            // A shell's mesh is two walls, the inner no larger than the outer.
            let walls = if r.mode == Mode::Shell { 2 } else { 1 };
            let mesh = if level_mesh { budget::level_mesh_bytes(spec, self.area).saturating_mul(walls) } else { 0 };
            budget::Estimate { writer: e.writer.saturating_add(labels).saturating_add(mesh), ..e }
        };
        budget::check(&self.spec, self.bounds, r.axis, limit, estimate)
    }

    /// What the output format's usual reader will not show of this grid ([`VoxelFormat::caveat`]), as notices.
    pub(crate) fn caveats(&self) -> Vec<super::Notice> {
        let caveat = self.request.format.and_then(|f| f.caveat(&self.spec));
        caveat.into_iter().map(|message| super::Notice { warning: true, message }).collect()
    }

    /// Refuses what measures distances in voxels that are not cubes: fields, shells and their level sets, and
    /// drain holes (round holes). Surfaces, solids and pockets are decided in the grid's frame, where every voxel
    /// is a unit cube, and need no distance.
    fn check_anisotropic(request: &Request, spec: &GridSpec) -> Result<(), EngineError> {
        let (what, instead) = if spec.is_cubic() {
            return Ok(());
        } else if request.mode.needs_field() {
            let instead = format!(
                "give one {}, or use {} or {} for the anisotropic grid",
                Setting::VoxelSize,
                Setting::Mode.with("surface"),
                Setting::Mode.with("solid")
            );
            (Setting::Mode.with(request.mode.name()).to_string(), instead)
        } else if *request.drain != DrainPlan::None {
            (Setting::Drain.to_string(), format!("give one {}, or leave out {}", Setting::VoxelSize, Setting::Drain))
        } else {
            return Ok(());
        };
        let [x, y, z] = spec.voxel_size.to_array();
        Err(EngineError::Anisotropic { what, x, y, z, instead })
    }

    /// The band a shell of `thickness` voxels is cut from ([`crate::voxel::shell::shell_band`]).
    fn shell_band(thickness: f32) -> Result<Band, EngineError> {
        let band = crate::voxel::shell::shell_band(thickness);
        match thickness > 0.0 && band <= MAX_BAND {
            true => Ok(Band::Voxels(band)),
            false => Err(EngineError::Level(format!(
                "{}: a shell's thickness is above 0 and at most {} voxels (this one is {thickness} voxels)",
                Setting::Thickness,
                MAX_BAND - 2.0
            ))),
        }
    }

    /// The band a level set needs: the request's, widened to hold the level with two voxels to spare.
    fn level_band(request: &Request, spec: &GridSpec) -> Result<Band, EngineError> {
        let level = request.level;
        if !level.is_finite() || (request.mode == Mode::Udf && level <= 0.0) {
            return Err(EngineError::Level(format!(
                "{}: {}",
                Setting::Level.with(level),
                match request.mode {
                    Mode::Udf => "an unsigned field's level set needs a level above 0 (the distance of the shell)",
                    _ => "a finite number of world units",
                }
            )));
        }
        let need = (level.abs() / spec.edge()) as f32 + 2.0;
        match request.band {
            Band::Voxels(k) if k >= need => Ok(request.band),
            Band::Full => Ok(Band::Full),
            Band::Voxels(_) if need <= MAX_BAND => Ok(Band::Voxels(need.ceil())),
            Band::Voxels(_) => Err(EngineError::Level(format!(
                "{} is {:.0} voxels from the surface; a band reaches at most {MAX_BAND}: a coarser grid or a level \
                 nearer 0",
                Setting::Level.with(level),
                need - 2.0
            ))),
        }
    }

    /// A failure of the run on this job's grid (a lattice or allocation error), named by the grid's size.
    pub(super) fn grid_error(&self, error: GridError) -> EngineError {
        let d = self.spec.dims;
        EngineError::Grid { mesh: format!("{}×{}×{} grid", d.x, d.y, d.z), error, sparse: self.sparse }
    }

    /// Triangles in the mesh.
    pub fn triangles(&self) -> u64 {
        self.mesh.triangles.len() as u64
    }
}
