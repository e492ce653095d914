//! `meshvox bench --suite sdf`: distance fields (band 3) on the bunny, the teapot, Spot and the ~1M-triangle
//! knot at 128, 512 and 1024 along the longest axis, on each backend, beside the surface of the same grid and
//! OpenVDB's `createLevelSetFromPolygons` in the same run (Debian's python3-openvdb through
//! `bench/openvdb_level_set.py`, on the same transform and half-width).

use super::{BenchArgs, Meshes, median, ms, open_engine};
use anyhow::{Context, Result, anyhow};
use meshvox::voxel::distance::Band;
use meshvox::voxel::{GridKind, Mode, Resolution};
use meshvox::{Engine, Request};
use std::time::Instant;

/// The band of the suite, OpenVDB's default half-width.
const BAND: f32 = 3.0;
pub(super) const SIZES: [u32; 3] = [128, 512, 1024];

#[derive(serde::Serialize)]
pub(super) struct SdfRow {
    mesh: String,
    triangles: usize,
    n: u32,
    dims: [u32; 3],
    backend: String,
    /// Median wall time of `Engine::voxelize` in surface mode, and in sdf mode (the surface, the inside for the
    /// sign and the distances), and of the sdf's field passes alone.
    surface_ms: f64,
    sdf_ms: f64,
    field_ms: f64,
    band_voxels: u64,
    /// OpenVDB's median on the same grid, and its active voxels.
    openvdb_ms: Option<f64>,
    openvdb_active: Option<u64>,
}

/// Median wall time and the last result of `runs` requests.
fn timed(
    engine: &Engine,
    name: &str,
    mesh: &meshvox::mesh::Mesh,
    request: &Request,
    runs: usize,
) -> Result<(f64, meshvox::Voxelized)> {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..runs.max(1) {
        drop(last.take());
        let t = Instant::now();
        let out = engine.voxelize(name, mesh, request)?;
        times.push(ms(t));
        last = Some(out);
    }
    Ok((median(times), last.ok_or_else(|| anyhow!("no runs"))?))
}

/// OpenVDB's level set of `mesh` on `spec`'s transform: (median ms, active voxels), or `None` (said) where
/// pyopenvdb is not there.
fn openvdb(dir: &std::path::Path, spec: &meshvox::voxel::GridSpec, runs: usize) -> Option<(f64, u64)> {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/bench/openvdb_level_set.py");
    let o = spec.origin;
    let out = std::process::Command::new("/usr/bin/python3")
        .arg(script)
        .arg(dir.join("vertices.npy"))
        .arg(dir.join("faces.npy"))
        .arg(format!("{},{},{}", o.x, o.y, o.z))
        .arg(spec.voxel_size.x.to_string())
        .arg(BAND.to_string())
        .arg(runs.max(1).to_string())
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let j: serde_json::Value = serde_json::from_slice(&o.stdout).ok()?;
            Some((j["seconds"].as_f64()? * 1e3, j["active"].as_u64()?))
        }
        other => {
            eprintln!("note: OpenVDB's time left out (pyopenvdb: apt-get install python3-openvdb): {other:?}");
            None
        }
    }
}

/// The mesh's shared vertices and faces as `.npy` files in `dir`, for OpenVDB.
fn write_arrays(dir: &std::path::Path, mesh: &meshvox::mesh::Mesh) -> Result<()> {
    let (positions, faces) = meshvox::mesh::to_indexed(mesh);
    let npy = |name: &str, descr: &str, rows: usize, bytes: Vec<u8>| -> Result<()> {
        let mut out = Vec::new();
        meshvox::formats::npy::write_npy_header(descr, &format!("({rows}, 3)"), &mut out)?;
        out.extend(bytes);
        std::fs::write(dir.join(name), out).with_context(|| format!("{}: cannot write", dir.display()))
    };
    let v: Vec<u8> = positions.iter().flat_map(|p| p.to_array()).flat_map(f64::to_le_bytes).collect();
    let f: Vec<u8> = faces.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
    npy("vertices.npy", "<f8", positions.len(), v)?;
    npy("faces.npy", "<u4", faces.len(), f)
}

/// Every case on every backend, with OpenVDB's time per mesh and size.
pub(super) fn run(args: &BenchArgs, meshes: &Meshes) -> Result<Vec<SdfRow>> {
    let dir = tempfile::tempdir()?;
    let engines: Vec<Engine> = args
        .backends
        .iter()
        .filter_map(|&b| match open_engine(b) {
            Ok(e) if b != meshvox::Backend::Gpu || e.uses_gpu() => Some(e),
            _ => None,
        })
        .collect();
    let mut rows = Vec::new();
    for (name, mesh) in meshes {
        write_arrays(dir.path(), mesh)?;
        for n in SIZES {
            // Grids past a few hundred million voxels are timed once.
            let runs = if n >= 1024 { 1 } else { args.runs };
            let surface = Request { grid: GridKind::Dense, ..Request::new(Resolution::Count(n), Mode::Surface) };
            let sdf = Request { band: Band::Voxels(BAND), ..Request { mode: Mode::Sdf, ..surface } };
            let spec = meshvox::engine::Job::plan(name, mesh, &sdf)?.spec;
            let vdb = openvdb(dir.path(), &spec, runs);
            for engine in &engines {
                let (surface_ms, _) = timed(engine, name, mesh, &surface, runs)?;
                let (sdf_ms, out) = timed(engine, name, mesh, &sdf, runs)?;
                let report = &out.report;
                let row = SdfRow {
                    mesh: name.clone(),
                    triangles: mesh.triangles.len(),
                    n,
                    dims: report.dims,
                    backend: report.field_backend.clone().unwrap_or_else(|| report.backend.clone()),
                    surface_ms,
                    sdf_ms,
                    field_ms: report.field_ms.unwrap_or(f64::NAN),
                    band_voxels: report.band_voxels.unwrap_or(0),
                    openvdb_ms: vdb.map(|v| v.0),
                    openvdb_active: vdb.map(|v| v.1),
                };
                eprintln!("{name} @{n} sdf: {sdf_ms:.0} ms (surface {surface_ms:.0} ms) on {}", row.backend);
                rows.push(row);
            }
        }
    }
    Ok(rows)
}

/// The suite's table and the two ratios the targets are stated in.
pub(super) fn table(rows: &[SdfRow]) -> String {
    let mut md = String::from(
        "| mesh | triangles | N | grid | backend | surface ms | sdf ms | of which field ms | sdf / surface | band voxels | OpenVDB ms | OpenVDB active | OpenVDB / meshvox |\n\
         |---|---:|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let [x, y, z] = r.dims;
        let vdb = |f: &dyn Fn(f64) -> String| r.openvdb_ms.map_or("-".to_string(), f);
        md += &format!(
            "| {} | {} | {} | {x}x{y}x{z} | {} | {:.1} | {:.1} | {:.1} | {:.1}x | {} | {} | {} | {} |\n",
            r.mesh,
            r.triangles,
            r.n,
            r.backend,
            r.surface_ms,
            r.sdf_ms,
            r.field_ms,
            r.sdf_ms / r.surface_ms,
            r.band_voxels,
            vdb(&|v| format!("{v:.0}")),
            r.openvdb_active.map_or("-".to_string(), |a| a.to_string()),
            vdb(&|v| format!("{:.2}x", v / r.sdf_ms)),
        );
    }
    md
}
