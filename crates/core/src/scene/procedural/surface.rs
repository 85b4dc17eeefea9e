//! From a field to a finished, symmetric triangle mesh with about the requested vertex count:
//! half-grid marching tetrahedra, optional clipping, edge-collapse simplification,
//! relaxation, mirroring and removal of stray pieces.

use crate::geometry::{TriMesh, Vec3};

use super::marching::{self, HalfMesh};
use super::remesh::{self, Field};

/// What surface to build.
pub struct SurfaceSpec<'a> {
    /// Zero set = surface, positive outside; must be symmetric in `x`.
    pub field: Field<'a>,
    /// Optional region: the surface is kept where `region(p) <= 0`; symmetric in `x`.
    pub region: Option<Field<'a>>,
    /// Lower corner of the grid box (its `x` is ignored: the half grid starts at `x = 0`).
    pub lo: Vec3,
    /// Upper corner of the grid box.
    pub hi: Vec3,
    /// Wanted number of vertices of the whole (mirrored) mesh.
    pub target_vertices: usize,
    /// Rough surface area in m², used for the first choice of grid spacing.
    pub area_estimate_m2: f32,
}

/// Vertices per m² of a marching-tetrahedra surface for a unit grid spacing (measured).
const MT_DENSITY: f32 = 4.5;
/// Grid spacing bounds in metres.
const H_MIN_M: f32 = 0.002;
const H_MAX_M: f32 = 0.015;
/// Relaxation passes after simplification.
const RELAX_PASSES: usize = 8;

fn extract(spec: &SurfaceSpec, h: f32) -> HalfMesh {
    let half = marching::extract_half(spec.field, spec.lo, spec.hi, h);
    match spec.region {
        Some(region) => marching::clip(&half, region, 0.2 * h),
        None => half,
    }
}

/// Builds the surface described by `spec`. Errors are plain messages about what failed.
pub fn build(spec: &SurfaceSpec) -> Result<TriMesh, String> {
    let target = spec.target_vertices.max(50);
    let spacing = |area: f32, density: f32| {
        (density * area / (3.0 * target as f32))
            .sqrt()
            .clamp(H_MIN_M, H_MAX_M)
    };
    let mut h = spacing(spec.area_estimate_m2.max(1e-3), MT_DENSITY);
    let mut half = extract(spec, h);
    let full_count = |m: &HalfMesh| 2 * m.positions.len();
    if full_count(&half) < 2 * target && h > H_MIN_M {
        // Re-derive the spacing from what this grid produced.
        let area = 2.0 * marching::area_m2(&half);
        if area > 0.0 {
            let density = full_count(&half) as f32 * h * h / area;
            h = spacing(area, density.max(1.0));
            half = extract(spec, h);
        }
    }
    if half.faces.is_empty() {
        return Err("the field has no surface inside the grid box".into());
    }
    let area = 2.0 * marching::area_m2(&half);
    let mean_edge_m = (1.155 * area / target as f32).sqrt();
    let simplified = remesh::simplify(&half, target, spec.field, 2.5 * mean_edge_m);
    let mut relaxed = simplified;
    for _ in 0..2 {
        relaxed = remesh::flip_edges(&relaxed, 4);
        relaxed = remesh::relax(&relaxed, spec.field, spec.region, RELAX_PASSES / 2);
    }
    let full = marching::largest_component(&marching::mirror(&relaxed));
    let mesh = TriMesh::new(full.positions, full.faces).map_err(|e| e.to_string())?;
    let report = mesh.report();
    if !report.is_clean() {
        return Err(format!(
            "generated mesh is not clean: {} degenerate, {} duplicate faces, {} non-manifold edges",
            report.degenerate_faces.len(),
            report.duplicate_faces.len(),
            report.non_manifold_edges.len()
        ));
    }
    Ok(mesh)
}
