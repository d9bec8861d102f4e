//! Mesh model: the paper's "poly" comparison backend (sec. 3.5, approach two). Each polygon's
//! adaptive quadtree is triangulated without cracks, every triangle carries the radiosity samples
//! at its vertices, and the triangles are Gouraud-shaded by the *same* rasterizer and deferred
//! shading pass as the direct method, so only the reconstruction differs.
//!
//! How it fits the renderer without changing it: every mesh triangle becomes a scene polygon of
//! its own (a triangle, stored as the collapsed quad c3 == c2 of [`scene::Polygon`]), whose
//! parametric map P(s, t) = (1 - s)(1 - t) c0 + s (1 - t) c1 + t c2 has the barycentric weights
//! ((1 - s)(1 - t), s (1 - t), t). Gouraud interpolation of the vertex colours C0, C1, C2 over it
//! is C(s, t) = C0 + s (C1 - C0) + t (C2 - C0) + s t (C0 - C1), a patch of degree (1, 1): a
//! [`PatchCoeffs::whole`] whose only non-zero power coefficients are those of 1, s, t and s t. The
//! rasterizer recovers (s, t) exactly per sample (perspective-correct), so the shading is the
//! world-space linear interpolation of the vertex colours, perspective-correct. [`MeshModel`] is
//! then both the scene to rasterize and its [`PatchSource`] (one patch per triangle).
//!
//! Triangulation (per leaf of each polygon's quadtree, all decisions on integer lattice keys):
//! - the leaf's boundary is walked counter-clockwise from its corner (0,0); each edge contributes
//!   the vertices of finer neighbours strictly inside it (the T-vertices). They are found by
//!   recursive bisection: a vertex lies strictly inside a leaf's edge only if the same-size cell
//!   across the edge is subdivided, and then the edge's midpoint is a corner of that cell's
//!   children; so "is the midpoint a vertex key?" (a binary search in the sorted keys), applied
//!   recursively to both halves, finds exactly the T-vertices of the edge, in order, at a cost of
//!   O(log n) per T-vertex found plus one search per edge;
//! - the leaf is fanned from the first of its corners (in the order (0,0), (1,0), (1,1), (0,1))
//!   whose two incident edges hold no T-vertex: with no T-vertex at all this is the two triangles
//!   split along the (0,0)-(1,1) diagonal, a fixed, data-independent choice (with only the four
//!   corner samples no diagonal fits the samples better: both predict the centre equally far from
//!   the bilinear mean), so the mesh's coverage never depends on the radiosity;
//! - if every corner touches an edge with T-vertices, the leaf is fanned from its centre, an extra
//!   vertex whose colour is the bilinear value there (the mean of the four corner samples).
//!
//! No T-junction is left: every vertex lying on a leaf's boundary is a vertex of that leaf's
//! triangles, and both sides of every edge use the same keys, hence the same `f64` world points
//! (one function, [`scene::Polygon::point`], the solver's own map, evaluated on the same
//! inputs), which the rasterizer snaps to the same fixed-point positions. Triangles of zero world
//! area (the leaves along the collapsed v = 1 edge of a triangular polygon) are dropped, which
//! changes no coverage. Fans keep the counter-clockwise (u, v) order, and the bilinear map of a
//! convex polygon preserves orientation, so every triangle winds like its parent (its normal is
//! its own Newell normal, equal to the parent's for a planar parent).
//!
//! Across polygons ([`MeshModel::build_with`]): along every seam the reconstruction joins
//! ([`crate::seam`]), each polygon's border also carries its neighbour's seam points (put into
//! the leaf edge's ring like T-vertices, ordered along the edge), and every seam point is
//! coloured with the mean of the samples there, so both sides of the seam have the same
//! vertices with the same colours: the Gouraud surface is continuous across it, with no
//! T-junction.
//!
//! Vertex colours are the samples themselves ([`SampledQuadtree::sample`]), except at seam
//! points (the mean of the polygons' samples there, which agree within 2 %); a missing or
//! non-finite sample is an [`Error::Inconsistent`]. Model size ([`MeshStats::bytes`]) is counted as
//! the paper's Table 1 counts a triangle mesh with per-vertex colour: 3 x f32 position + 3 x f32
//! colour per vertex (`BYTES_PER_VERTEX`) and 3 x u32 indices per triangle
//! (`BYTES_PER_TRIANGLE`).

use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

use super::PatchSource;
use base::error::{Error, Result};
use base::quadtree::{SampledQuadtree, VertexKey};
use scene::{Polygon, Scene, Shape};

use super::PatchCoeffs;

/// Bytes per mesh vertex in [`MeshStats::bytes`]: 3 x f32 position + 3 x f32 colour.
pub(crate) const BYTES_PER_VERTEX: u64 = 24;
/// Bytes per mesh triangle in [`MeshStats::bytes`]: 3 x u32 vertex indices.
pub(crate) const BYTES_PER_TRIANGLE: u64 = 12;

/// Sizes of a triangle model, as the paper's Table 1 counts them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct MeshStats {
    /// Triangles (zero-area ones excluded).
    pub triangles: u64,
    /// Distinct vertices: (polygon, lattice key) pairs used by at least one triangle, plus fan
    /// centres.
    pub vertices: u64,
    /// T-vertices of the quadtrees (vertices strictly inside an edge of a coarser leaf).
    pub t_vertices: u64,
    /// Model size: `vertices * BYTES_PER_VERTEX + triangles * BYTES_PER_TRIANGLE`.
    pub bytes: u64,
}

impl MeshStats {
    fn with_bytes(triangles: u64, vertices: u64, t_vertices: u64) -> MeshStats {
        MeshStats {
            triangles,
            vertices,
            t_vertices,
            bytes: vertices * BYTES_PER_VERTEX + triangles * BYTES_PER_TRIANGLE,
        }
    }

    /// The same counts for the scene's original model: 2 triangles per quad, 1 per triangle;
    /// vertices are the distinct corner positions over the whole scene (bit-exact equality, so
    /// corners shared by polygons count once); no T-vertices.
    pub fn original(scene: &Scene) -> MeshStats {
        let mut corners: Vec<[u64; 3]> = Vec::new();
        let mut triangles = 0u64;
        for p in &scene.polygons {
            triangles += match p.shape {
                Shape::Triangle => 1,
                Shape::Quad => 2,
            };
            corners.extend(p.vertices().iter().map(|c| c.to_array().map(f64::to_bits)));
        }
        corners.sort_unstable();
        corners.dedup();
        MeshStats::with_bytes(triangles, corners.len() as u64, 0)
    }
}

/// The Gouraud mesh of a radiosity solution: a scene of triangles and one degree-(1, 1) patch per
/// triangle. Render it with `Shader::Gouraud(&mesh.gouraud)` over `mesh.scene`; as a patch
/// source (`frame::render_patches(&mesh.scene, camera, &mesh, &opts)`) it gives the same bits
/// through the region patch tables.
#[derive(Debug, Clone)]
pub struct MeshModel {
    /// The input scene with its polygons replaced by the triangles (camera, materials, spots and
    /// every setting kept). Triangle `k` is `scene.polygons[k]`.
    pub scene: Scene,
    /// Triangle `k`'s Gouraud patch in the 52 bytes of its non-zero coefficients
    /// ([`GouraudPatch`]), from which [`MeshModel::patch`] builds the full patch: a frame reads
    /// these where it read 208-byte patches (a 10^5-triangle mesh's patches, read in the
    /// renderers' round-robin order, came mostly from memory: a third of its frame).
    pub gouraud: Vec<GouraudPatch>,
    /// Index of the input polygon triangle `k` came from.
    pub source_polygon: Vec<u32>,
    /// Parameters (u, v) in the source polygon's domain of triangle `k`'s vertices c0, c1, c2.
    pub parent_uv: Vec<[[f64; 2]; 3]>,
    /// Counts and size.
    pub stats: MeshStats,
}

/// A vertex of a leaf's triangulation, before mapping to world space.
#[derive(Debug, Clone, Copy)]
struct MeshVertex {
    /// Distinct id within the polygon: the sample index, or `keys.len() + n` for the n-th centre.
    id: u32,
    /// Parameters in the polygon's domain.
    uv: [f64; 2],
    /// Colour.
    colour: Vec3,
}

/// One polygon's triangulation in its parameter domain.
#[derive(Debug, Default)]
struct DomainMesh {
    triangles: Vec<[MeshVertex; 3]>,
    t_vertices: u64,
    centres: u32,
}

/// Appends to `out` the indices (into `keys`) of the vertices strictly inside the lattice
/// segment a -> b (axis-aligned, a dyadic cell edge), in order from a to b. See the module docs
/// for why bisection finds exactly the T-vertices.
fn edge_vertices(a: VertexKey, b: VertexKey, keys: &[VertexKey], out: &mut Vec<usize>) {
    let len = a.i.abs_diff(b.i) + a.j.abs_diff(b.j);
    if len < 2 {
        return;
    }
    let m = VertexKey::new((a.i + b.i) / 2, (a.j + b.j) / 2);
    if let Ok(idx) = keys.binary_search(&m) {
        edge_vertices(a, m, keys, out);
        out.push(idx);
        edge_vertices(m, b, keys, out);
    }
}

fn sample_vertex(sq: &SampledQuadtree, polygon: usize, idx: usize) -> Result<MeshVertex> {
    let k = sq.keys[idx];
    let colour = sq.values.get(idx).copied().ok_or_else(|| {
        Error::Inconsistent(format!(
            "mesh: polygon {polygon}: no sample at vertex ({}, {})",
            k.i, k.j
        ))
    })?;
    if !colour.is_finite() {
        return Err(Error::Inconsistent(format!(
            "mesh: polygon {polygon}: non-finite sample at vertex ({}, {})",
            k.i, k.j
        )));
    }
    Ok(MeshVertex {
        id: idx as u32,
        uv: [k.u(), k.v()],
        colour,
    })
}

/// One polygon's seam points ([`crate::seam::mesh_points`]): colours replacing its own samples'
/// (`shared`, sorted by key) and points of its neighbours its border must carry (`extra`, sorted
/// by key; vertex ids `keys.len() + n`).
#[derive(Debug, Default)]
struct Border {
    shared: Vec<(VertexKey, Vec3)>,
    extra: Vec<(VertexKey, Vec3)>,
}

impl Border {
    fn of(sq: &SampledQuadtree, points: &[(VertexKey, Vec3)]) -> Border {
        let (shared, extra) = points
            .iter()
            .partition(|(k, _)| sq.keys.binary_search(k).is_ok());
        Border { shared, extra }
    }

    /// Ids of the extra points strictly inside the border segment a -> b (axis-aligned), in any
    /// order.
    fn inside(&self, a: VertexKey, b: VertexKey, base: usize, out: &mut Vec<usize>) {
        let l = base::quadtree::LATTICE;
        let on_border =
            (a.i == b.i && (a.i == 0 || a.i == l)) || (a.j == b.j && (a.j == 0 || a.j == l));
        if !on_border {
            return;
        }
        let (ilo, ihi) = (a.i.min(b.i), a.i.max(b.i));
        let (jlo, jhi) = (a.j.min(b.j), a.j.max(b.j));
        for (x, (k, _)) in self.extra.iter().enumerate() {
            let inside = if a.i == b.i {
                k.i == a.i && k.j > jlo && k.j < jhi
            } else {
                k.j == a.j && k.i > ilo && k.i < ihi
            };
            if inside {
                out.push(base + x);
            }
        }
    }
}

/// The mesh vertex with id `r`: a sample (coloured by the seam where it is a seam point) or an
/// extra border point.
fn vertex(sq: &SampledQuadtree, border: &Border, polygon: usize, r: usize) -> Result<MeshVertex> {
    let n = sq.keys.len();
    if r >= n {
        let (k, colour) = border.extra[r - n];
        return Ok(MeshVertex {
            id: r as u32,
            uv: [k.u(), k.v()],
            colour,
        });
    }
    let mut v = sample_vertex(sq, polygon, r)?;
    if let Ok(x) = border.shared.binary_search_by_key(&sq.keys[r], |e| e.0) {
        v.colour = border.shared[x].1;
    }
    Ok(v)
}

/// The key of vertex id `r`.
fn key_of(sq: &SampledQuadtree, border: &Border, r: usize) -> VertexKey {
    sq.keys
        .get(r)
        .copied()
        .unwrap_or_else(|| border.extra[r - sq.keys.len()].0)
}

/// Triangulates one polygon's quadtree in its domain (module docs: fans, T-vertices, seam
/// points on the border).
fn triangulate(sq: &SampledQuadtree, polygon: usize, border: &Border) -> Result<DomainMesh> {
    let keys = &sq.keys;
    let first_centre = keys.len() + border.extra.len();
    let mut mesh = DomainMesh::default();
    let mut ring: Vec<usize> = Vec::new();
    let mut segment: Vec<usize> = Vec::new();
    let mut verts: Vec<MeshVertex> = Vec::new();
    for leaf in sq.tree.leaves() {
        let cell = sq.tree.node(leaf).cell;
        let corners = cell.corners();
        let mut corner_idx = [0usize; 4];
        for (c, k) in corners.iter().enumerate() {
            corner_idx[c] = keys.binary_search(k).map_err(|_| {
                Error::Inconsistent(format!(
                    "mesh: polygon {polygon}: no sample at leaf corner ({}, {})",
                    k.i, k.j
                ))
            })?;
        }
        // The boundary ring, counter-clockwise from corner 0; ring_at[c] = position of corner c;
        // busy[e] = whether edge e (corner e -> corner e + 1) holds T-vertices or seam points.
        ring.clear();
        let mut ring_at = [0usize; 4];
        let mut busy = [false; 4];
        for e in 0..4 {
            ring_at[e] = ring.len();
            ring.push(corner_idx[e]);
            let (a, b) = (corners[e], corners[(e + 1) % 4]);
            segment.clear();
            edge_vertices(a, b, keys, &mut segment);
            mesh.t_vertices += segment.len() as u64;
            let own = segment.len();
            border.inside(a, b, keys.len(), &mut segment);
            if segment.len() > own {
                // Seam points interleave with the T-vertices: order all by distance from a.
                let dist = |r: &usize| {
                    let k = key_of(sq, border, *r);
                    k.i.abs_diff(a.i) + k.j.abs_diff(a.j)
                };
                segment.sort_unstable_by_key(dist);
            }
            busy[e] = !segment.is_empty();
            ring.extend_from_slice(&segment);
        }
        verts.clear();
        for &r in &ring {
            verts.push(vertex(sq, border, polygon, r)?);
        }
        let n = verts.len();
        // Corner c touches edges c - 1 and c.
        match (0..4).find(|&c| !busy[c] && !busy[(c + 3) % 4]) {
            Some(c) => {
                // Fan from corner c: the ring from c; its neighbours on the ring are the adjacent
                // corners, so the n - 2 triangles (c, r_j, r_j+1) for j = 1..n-2 are non-degenerate.
                let r = |j: usize| verts[(ring_at[c] + j) % n];
                for j in 1..n - 1 {
                    mesh.triangles.push([r(0), r(j), r(j + 1)]);
                }
            }
            None => {
                // Fan from the centre, coloured with the bilinear value there (mean of corners).
                let (u0, v0, u1, v1) = cell.bounds();
                let mean = ring_at
                    .iter()
                    .map(|&r| verts[r].colour)
                    .fold(Vec3::ZERO, |a, b| a + b)
                    * 0.25;
                let centre = MeshVertex {
                    id: (first_centre as u32).saturating_add(mesh.centres),
                    uv: [0.5 * (u0 + u1), 0.5 * (v0 + v1)],
                    colour: mean,
                };
                mesh.centres += 1;
                for j in 0..n {
                    mesh.triangles.push([centre, verts[j], verts[(j + 1) % n]]);
                }
            }
        }
    }
    Ok(mesh)
}

/// The Gouraud patch of a triangle with vertex colours `c` at its (s, t) = (0,0), (1,0), (0|1, 1).
pub fn gouraud_patch(c: [Vec3; 3]) -> PatchCoeffs {
    GouraudPatch::of(c).patch()
}

/// A triangle's Gouraud patch held as its only non-zero coefficients: per channel
/// `k = [k0, k1, k4, k5]` = [C0, C1 - C0, C2 - C0, C0 - C1] of the power basis 1, s, t, s t
/// (every other coefficient +0); [`GouraudPatch::patch`] is the full patch.
///
/// Invariant: no coefficient is -0, so the full patch is always flagged
/// [`PatchCoeffs::bilinear`] and the engine's Gouraud shader evaluates every triangle from
/// these 48 bytes in the degree-(1, 1) form. [`GouraudPatch::of`] makes it hold by reading a
/// vertex colour of -0 as +0 (radiosity is not signed; a difference of two numbers neither of
/// which is -0 is never -0 in round-to-nearest).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GouraudPatch {
    k: [[f32; 4]; 3],
}

impl GouraudPatch {
    /// The patch of vertex colours `c` (-0 read as +0).
    pub fn of(c: [Vec3; 3]) -> GouraudPatch {
        // `x + 0.0` is x for every x but -0, which it maps to +0.
        let c = c.map(|v| v + Vec3::ZERO);
        let mut k = [[0.0f32; 4]; 3];
        for ch in 0..3 {
            let (c0, c1, c2) = (c[0][ch], c[1][ch], c[2][ch]);
            k[ch] = [c0, c1 - c0, c2 - c0, c0 - c1];
        }
        GouraudPatch { k }
    }

    /// Per channel (R, G, B): k0, k1, k4, k5.
    #[inline]
    pub fn coefficients(&self) -> &[[f32; 4]; 3] {
        &self.k
    }

    /// The full patch (flagged bilinear: see the invariant).
    pub fn patch(&self) -> PatchCoeffs {
        let mut c = [[0.0f32; 16]; 3];
        for (c, k) in c.iter_mut().zip(&self.k) {
            [c[0], c[1], c[4], c[5]] = *k;
        }
        let p = PatchCoeffs::whole(c);
        debug_assert!(p.bilinear, "{self:?}");
        p
    }
}

/// One polygon's finished triangles.
struct PolygonMesh {
    triangles: Vec<Polygon>,
    gouraud: Vec<GouraudPatch>,
    uv: Vec<[[f64; 2]; 3]>,
    vertices: u64,
    t_vertices: u64,
}

fn mesh_polygon(
    parent: &Polygon,
    sq: &SampledQuadtree,
    polygon: usize,
    points: &[(VertexKey, Vec3)],
) -> Result<PolygonMesh> {
    if sq.values.len() != sq.keys.len() {
        return Err(Error::Inconsistent(format!(
            "mesh: polygon {polygon}: {} samples for {} vertices",
            sq.values.len(),
            sq.keys.len()
        )));
    }
    let border = Border::of(sq, points);
    let dm = triangulate(sq, polygon, &border)?;
    let mut out = PolygonMesh {
        triangles: Vec::with_capacity(dm.triangles.len()),
        gouraud: Vec::with_capacity(dm.triangles.len()),
        uv: Vec::with_capacity(dm.triangles.len()),
        vertices: 0,
        t_vertices: dm.t_vertices,
    };
    let mut used = vec![false; sq.keys.len() + border.extra.len() + dm.centres as usize];
    for tri in &dm.triangles {
        let world = tri.map(|v| parent.point(v.uv[0], v.uv[1]));
        // `None`: zero world area (collapsed edge of a triangular parent); covers no sample.
        let Some(mut t) = Polygon::triangle(world, parent.material, parent.object) else {
            continue;
        };
        // Drawn where its polygon is: from behind only if faces lie over it, from in front
        // only if a face lies back to back with it.
        t.sealed = parent.sealed;
        t.backed = parent.backed;
        for v in tri {
            used[v.id as usize] = true;
        }
        out.triangles.push(t);
        out.gouraud.push(GouraudPatch::of(tri.map(|v| v.colour)));
        out.uv.push(tri.map(|v| v.uv));
    }
    out.vertices = used.iter().filter(|&&u| u).count() as u64;
    Ok(out)
}

impl MeshModel {
    /// The Gouraud patch of triangle `k` (over the triangle's own (s, t)), built from its vertex
    /// coefficients. Panics when `k` is not a triangle of the mesh.
    #[inline]
    pub fn patch(&self, k: usize) -> PatchCoeffs {
        self.gouraud[k].patch()
    }

    /// Builds the mesh of a solution: `polygons` holds one sampled quadtree per scene polygon, in
    /// scene order (`Solution::polygons`). Fails with [`Error::Inconsistent`] if the counts differ, a
    /// leaf vertex has no sample, a sample is not finite, or the mesh would exceed `u32` ids.
    pub fn build(scene: &Scene, polygons: &[SampledQuadtree]) -> Result<MeshModel> {
        MeshModel::build_with(scene, polygons, &crate::Seams::none())
    }

    /// [`MeshModel::build`], sharing vertices across `seams`: every seam point is a vertex of
    /// both polygons' triangles, coloured with the mean of the samples there, so the mesh is one
    /// continuous surface across the seam (the same points the RRPs join,
    /// [`crate::seam`]).
    pub fn build_with(
        scene: &Scene,
        polygons: &[SampledQuadtree],
        seams: &crate::Seams,
    ) -> Result<MeshModel> {
        if polygons.len() != scene.polygons.len() {
            return Err(Error::Inconsistent(format!(
                "mesh: {} quadtrees for {} polygons",
                polygons.len(),
                scene.polygons.len()
            )));
        }
        let points = crate::seam::mesh_points(seams, polygons);
        let parts: Vec<PolygonMesh> = scene
            .polygons
            .par_iter()
            .zip(polygons.par_iter())
            .enumerate()
            .map(|(i, (p, sq))| mesh_polygon(p, sq, i, &points[i]))
            .collect::<Result<_>>()?;
        let total: usize = parts.iter().map(|p| p.triangles.len()).sum();
        if total >= u32::MAX as usize {
            return Err(Error::Inconsistent(format!(
                "mesh: {total} triangles exceed the u32 polygon ids"
            )));
        }
        let mut tris = Vec::with_capacity(total);
        let mut gouraud = Vec::with_capacity(total);
        let mut parent_uv = Vec::with_capacity(total);
        let mut source_polygon = Vec::with_capacity(total);
        let (mut vertices, mut t_vertices) = (0u64, 0u64);
        for (i, part) in parts.into_iter().enumerate() {
            source_polygon.extend(std::iter::repeat_n(i as u32, part.triangles.len()));
            tris.extend(part.triangles);
            gouraud.extend(part.gouraud);
            parent_uv.extend(part.uv);
            vertices += part.vertices;
            t_vertices += part.t_vertices;
        }
        let stats = MeshStats::with_bytes(tris.len() as u64, vertices, t_vertices);
        let mut out_scene = scene.clone();
        out_scene.polygons = tris;
        Ok(MeshModel {
            scene: out_scene,
            gouraud,
            source_polygon,
            parent_uv,
            stats,
        })
    }
}

/// Each triangle is one scene polygon with one patch: the patch id is the polygon id.
impl PatchSource for MeshModel {
    #[inline]
    fn locate(&self, polygon: u32, _u: f32, _v: f32) -> u32 {
        polygon
    }

    #[inline]
    fn patch(&self, id: u32) -> PatchCoeffs {
        MeshModel::patch(self, id as usize)
    }

    /// `locate` answers `id` on the whole closed domain [0, 1]^2 (and beyond); as a half-open
    /// f32 rectangle that is `[0, 1 + 2^-23)` per axis, 1 + 2^-23 being the next f32 after 1, so
    /// `u < 1 + 2^-23` holds exactly when `u <= 1`. Samples outside it (the rasterizer clamps
    /// (u, v) into [0, 1], so there are none) would only fall back to `locate`.
    #[inline]
    fn cell(&self, _id: u32) -> Option<[f32; 4]> {
        let hi = 1.0 + f32::EPSILON;
        Some([0.0, hi, 0.0, hi])
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use base::quadtree::{Quadtree, LATTICE};
    use glam::DVec3;
    use proptest::prelude::*;
    use scene::{Camera, Material, Projection};

    /// f32 unit roundoff.
    const U32: f64 = f32::EPSILON as f64 / 2.0;

    /// A scene with one quad `corners`, seen orthographically from +z over [0, 1]^2.
    fn scene_of(corners: [DVec3; 4], size: u32) -> Scene {
        let camera = Camera {
            eye: DVec3::new(0.5, 0.5, 2.0),
            look_at: DVec3::new(0.5, 0.5, 0.0),
            up: DVec3::Y,
            projection: Projection::Orthographic {
                width: 1.0,
                height: 1.0,
            },
        };
        let m = Material {
            name: "white".into(),
            reflectance: DVec3::splat(0.5),
            emission: DVec3::ZERO,
        };
        Scene::new(
            camera,
            size,
            size,
            vec![m],
            vec![Polygon::quad(corners, 0, 0).unwrap()],
        )
    }

    pub(crate) fn unit_square(size: u32) -> Scene {
        scene_of(
            [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            size,
        )
    }

    /// A tree grown by splitting, in turn, the leaf `sel % leaf_count` (if above `max_level`).
    fn grow(sels: &[u32], max_level: u32) -> Quadtree {
        let mut t = Quadtree::new();
        for &s in sels {
            let leaves = t.leaves();
            let id = leaves[s as usize % leaves.len()];
            if t.node(id).cell.level < max_level {
                t.split(id);
            }
        }
        t
    }

    /// Signed area of a triangle in the (u, v) domain.
    fn uv_area(t: &[[f64; 2]; 3]) -> f64 {
        let (a, b, c) = (t[0], t[1], t[2]);
        0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    }

    /// Local (s, t) of parent point `p` in triangle `t` (collapsed-quad parameters), if inside.
    fn local_st(t: &[[f64; 2]; 3], p: [f64; 2]) -> Option<(f64, f64)> {
        let d = 2.0 * uv_area(t);
        let (a, b, c) = (t[0], t[1], t[2]);
        let lb = ((p[0] - a[0]) * (c[1] - a[1]) - (p[1] - a[1]) * (c[0] - a[0])) / d;
        let lc = ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])) / d;
        let la = 1.0 - lb - lc;
        let e = -1e-12;
        if la < e || lb < e || lc < e {
            return None;
        }
        let s = if lc < 1.0 { lb / (1.0 - lc) } else { 0.0 };
        Some((s.clamp(0.0, 1.0), lc.clamp(0.0, 1.0)))
    }

    /// Crack-freeness in the domain, exactly: every directed triangle edge (on lattice keys) not
    /// on the domain border has its reverse in exactly one other triangle, and no edge appears
    /// twice in one direction. A T-junction shows up as an edge with no reverse. (Coverage alone
    /// cannot see a T-junction on a planar, orthographic square: the vertex lies exactly on the
    /// coarse edge there.)
    fn assert_conforming(mesh: &MeshModel) {
        use std::collections::HashMap;
        let key = |x: [f64; 2]| {
            (
                (x[0] * LATTICE as f64) as u32,
                (x[1] * LATTICE as f64) as u32,
            )
        };
        type Point = (u32, u32);
        let mut edges: HashMap<(Point, Point), u32> = HashMap::new();
        for t in &mesh.parent_uv {
            for j in 0..3 {
                *edges.entry((key(t[j]), key(t[(j + 1) % 3]))).or_default() += 1;
            }
        }
        let border = |a: (u32, u32), b: (u32, u32)| {
            (a.0 == b.0 && (a.0 == 0 || a.0 == LATTICE))
                || (a.1 == b.1 && (a.1 == 0 || a.1 == LATTICE))
        };
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "edge {a:?} -> {b:?} used {n} times");
            if !border(a, b) {
                assert_eq!(
                    edges.get(&(b, a)),
                    Some(&1),
                    "edge {a:?} -> {b:?} has no twin"
                );
            }
        }
    }

    /// Largest |difference| between every triangle's patch at its vertices and the samples there.
    /// At (s, t) = (0, 0) the patch returns k0 = C0 exactly; at (1, 0) and (0, 1) it returns
    /// fl(fl(C1 - C0) + C0): two roundings, each at most u |result of that op| <= u 2M, so the
    /// error is below 4 u M with M the largest |sample| of the triangle.
    fn check_vertex_colours(mesh: &MeshModel, sq: &[SampledQuadtree]) {
        for k in 0..mesh.gouraud.len() {
            let p = &mesh.patch(k);
            let sqp = &sq[mesh.source_polygon[k] as usize];
            let uv = mesh.parent_uv[k];
            let key = |x: [f64; 2]| {
                VertexKey::new(
                    (x[0] * LATTICE as f64) as u32,
                    (x[1] * LATTICE as f64) as u32,
                )
            };
            let c: Vec<Option<Vec3>> = uv.iter().map(|&x| sqp.sample(key(x))).collect();
            let m = c
                .iter()
                .flatten()
                .map(|v| v.abs().max_element())
                .fold(0.0f32, f32::max) as f64;
            for (j, st) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)].iter().enumerate() {
                // Fan centres are not samples: their colour is checked by the linear test.
                let Some(want) = c[j] else {
                    continue;
                };
                let got = p.eval(st.0, st.1);
                let err = (got - want).abs().max_element() as f64;
                assert!(
                    err <= 4.0 * U32 * m,
                    "triangle {k} vertex {j}: {got} vs {want}"
                );
                if j == 0 {
                    assert_eq!(got, want, "C0 is reproduced exactly");
                }
            }
        }
    }

    #[test]
    fn hand_counted_tree_with_two_t_vertices() {
        // Root split, upper-right quadrant split: 7 leaves, 14 vertices, 2 T-vertices. The two
        // coarse leaves next to the split quadrant hold one T-vertex each, with a free corner
        // (0,0): 3 triangles each; the lower-left leaf 2; the 4 small leaves 2 each: 16.
        let mut t = Quadtree::new();
        let c = t.split(0);
        t.split(c + 3);
        let sq = SampledQuadtree::from_fn(t, |u, v| Vec3::new(u as f32, v as f32, 1.0));
        let mesh = MeshModel::build(&unit_square(8), std::slice::from_ref(&sq)).unwrap();
        assert_eq!(
            mesh.stats,
            MeshStats {
                triangles: 16,
                vertices: 14,
                t_vertices: 2,
                bytes: 14 * 24 + 16 * 12,
            }
        );
        assert_eq!(mesh.source_polygon, vec![0; 16]);
    }

    #[test]
    fn leaf_with_t_vertices_on_opposite_edges_is_fanned_from_its_centre() {
        // Level-2 grid (16 leaves); split (0,1) and (2,1): leaf (1,1) has T-vertices on its left
        // and right edges, so no corner is free: centre fan of 4 + 2 = 6 triangles. T-vertices:
        // the 4 edge midpoints of each split cell except (0,1)'s left one on the border: 7.
        // Five leaves hold one T-vertex each (3 triangles), 16 plain leaves (2 each): 6 + 15 +
        // 32 = 53 triangles. Vertices: 25 grid + 2 x 5 new + 1 centre = 36.
        let mut t = Quadtree::new();
        let c = t.split(0);
        for k in 0..4 {
            t.split(c + k);
        }
        for (x, y) in [(0, 1), (2, 1)] {
            let id = (0..t.nodes().len() as u32)
                .find(|&i| t.node(i).cell == base::quadtree::Cell { level: 2, x, y })
                .unwrap();
            t.split(id);
        }
        assert_eq!(t.t_vertices().len(), 7);
        let sq = SampledQuadtree::from_fn(t, |u, v| Vec3::new(u as f32, 1.0, v as f32));
        let mesh = MeshModel::build(&unit_square(64), std::slice::from_ref(&sq)).unwrap();
        assert_eq!(mesh.stats.triangles, 53);
        assert_eq!(mesh.stats.vertices, 36);
        assert_eq!(mesh.stats.t_vertices, 7);
        let area: f64 = mesh.parent_uv.iter().map(uv_area).sum();
        assert!((area - 1.0).abs() < 1e-15);
        assert_conforming(&mesh);
    }

    #[test]
    fn triangle_parent_drops_the_collapsed_top_row() {
        // A triangle over a level-2 grid: the 4 top-row leaves lose the triangle on their collapsed
        // v = 1 edge (zero world area), so 16 * 2 - 4 = 28 triangles. The dropped triangle
        // (k0, k2, k3) is the only one using the top-left key (0, 1): 25 - 1 = 24 vertices.
        let mut scene = unit_square(32);
        scene.polygons = vec![Polygon::triangle([DVec3::ZERO, DVec3::X, DVec3::Y], 0, 0).unwrap()];
        let mut t = Quadtree::new();
        let c = t.split(0);
        for k in 0..4 {
            t.split(c + k);
        }
        let sq = SampledQuadtree::from_fn(t, |u, _| Vec3::splat(u as f32));
        let mesh = MeshModel::build(&scene, std::slice::from_ref(&sq)).unwrap();
        assert_eq!(mesh.stats.triangles, 28);
        assert_eq!(mesh.stats.vertices, 24);
        for tri in &mesh.scene.polygons {
            assert!(tri.normal.dot(scene.polygons[0].normal) > 1.0 - 1e-12);
        }
        assert_eq!(MeshStats::original(&scene).triangles, 1);
        assert_eq!(MeshStats::original(&scene).vertices, 3);
        assert_eq!(MeshStats::original(&unit_square(8)).triangles, 2);
        assert_eq!(MeshStats::original(&unit_square(8)).bytes, 4 * 24 + 2 * 12);
    }

    #[test]
    fn missing_or_bad_samples_are_runtime_errors() {
        let mut t = Quadtree::new();
        t.split(0);
        let good = SampledQuadtree::from_fn(t, |_, _| Vec3::ONE);
        let scene = unit_square(8);
        let mut missing = good.clone();
        missing.keys.remove(4); // the centre
        missing.values.remove(4);
        assert!(matches!(
            MeshModel::build(&scene, &[missing]),
            Err(Error::Inconsistent(_))
        ));
        let mut nan = good.clone();
        nan.values[2] = Vec3::new(f32::NAN, 0.0, 0.0);
        assert!(matches!(
            MeshModel::build(&scene, &[nan]),
            Err(Error::Inconsistent(_))
        ));
        let mut short = good.clone();
        short.values.pop();
        assert!(matches!(
            MeshModel::build(&scene, &[short]),
            Err(Error::Inconsistent(_))
        ));
        assert!(matches!(
            MeshModel::build(&scene, &[]),
            Err(Error::Inconsistent(_))
        ));
    }

    #[test]
    fn cell_covers_exactly_the_closed_domain() {
        let hi = 1.0 + f32::EPSILON;
        assert_eq!(f32::from_bits(1.0f32.to_bits() + 1), hi);
        let sq = SampledQuadtree::from_fn(Quadtree::new(), |_, _| Vec3::ONE);
        let mesh = MeshModel::build(&unit_square(8), &[sq]).unwrap();
        assert_eq!(mesh.cell(1), Some([0.0, hi, 0.0, hi]));
        assert_eq!(mesh.locate(1, 1.0, 0.3), 1);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// Random unrestricted trees on the unit square: the (u, v) areas must tile the domain
        /// (f64 sums of dyadic areas: exact up to the rounding of a few hundred additions, far
        /// below 1e-12) without a T-junction (the rasterizer's coverage of the same meshes is
        /// checked in the engine's tests).
        #[test]
        fn random_trees_cover_like_the_polygon(sels in prop::collection::vec(any::<u32>(), 0..60)) {
            let t = grow(&sels, 7);
            let tv = t.t_vertices().len() as u64;
            let keys = t.vertex_keys().len() as u64;
            let sq = SampledQuadtree::from_fn(t, |u, v| {
                Vec3::new((3.0 * u + v) as f32, (u * v) as f32, 2.0)
            });
            let scene = unit_square(128);
            let mesh = MeshModel::build(&scene, std::slice::from_ref(&sq)).unwrap();
            prop_assert_eq!(mesh.stats.t_vertices, tv);
            prop_assert!(mesh.stats.vertices >= keys);
            let mut area = 0.0;
            for t in &mesh.parent_uv {
                let a = uv_area(t);
                prop_assert!(a > 0.0, "counter-clockwise, non-degenerate");
                area += a;
            }
            prop_assert!((area - 1.0).abs() < 1e-12, "area {}", area);
            assert_conforming(&mesh);
            check_vertex_colours(&mesh, std::slice::from_ref(&sq));
        }

        /// The same for the triangle (0,0), (1,0), (0,1): the triangles on the collapsed v = 1
        /// edge are dropped, so the check of tiling is on world area: the sum of the triangles'
        /// areas is the parent's 1/2 (dyadic areas again; each triangle's Newell area has a
        /// relative rounding of a few ulps).
        #[test]
        fn random_trees_on_a_triangle_cover_like_it(sels in prop::collection::vec(any::<u32>(), 0..60)) {
            let mut scene = unit_square(128);
            scene.polygons =
                vec![Polygon::triangle([DVec3::ZERO, DVec3::X, DVec3::Y], 0, 0).unwrap()];
            let sq = SampledQuadtree::from_fn(grow(&sels, 7), |u, v| {
                Vec3::new(u as f32, v as f32, 0.5)
            });
            let mesh = MeshModel::build(&scene, std::slice::from_ref(&sq)).unwrap();
            let area: f64 = mesh.scene.polygons.iter().map(|p| p.area).sum();
            prop_assert!((area - 0.5).abs() < 1e-12, "area {}", area);
            for p in &mesh.scene.polygons {
                prop_assert!(p.normal.dot(DVec3::Z) > 1.0 - 1e-12, "winding kept");
            }
            check_vertex_colours(&mesh, std::slice::from_ref(&sq));
        }

        /// The shader takes its degree-(1, 1) form for every Gouraud patch (bit-identical, see
        /// `PatchCoeffs::bilinear_exact`), zeros of either sign among the colours included (-0
        /// is read as +0), and the patch holds C0, C1 - C0, C2 - C0, C0 - C1.
        #[test]
        fn gouraud_patches_take_the_bilinear_evaluation(
            c in prop::array::uniform9(0.0f32..10.0),
            signs in prop::array::uniform9(any::<bool>()),
            zeros in prop::array::uniform9(any::<bool>()),
        ) {
            let x = |i: usize| {
                let x = if zeros[i] { 0.0 } else { c[i] };
                if signs[i] { -x } else { x }
            };
            let v = |i: usize| Vec3::new(x(3 * i), x(3 * i + 1), x(3 * i + 2));
            let p = gouraud_patch([v(0), v(1), v(2)]);
            prop_assert!(p.bilinear);
            for ch in 0..3 {
                let plus = |i: usize| x(3 * i + ch) + 0.0;
                let (c0, c1, c2) = (plus(0), plus(1), plus(2));
                let want = [c0, c1 - c0, c2 - c0, c0 - c1];
                let got = [p.c[ch][0], p.c[ch][1], p.c[ch][4], p.c[ch][5]];
                prop_assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits));
                prop_assert!(c0.to_bits() != 0x8000_0000);
            }
        }

        /// Gouraud reproduces a linear function on a parallelogram (where world-linear equals
        /// (u, v)-linear), at any point of any triangle, fan centres included. Error budget with
        /// M = max |f| and u = 2^-24: samples rounded to f32 (u M); coefficients k1, k4, k5
        /// rounded (u 2M each); Horner's 2 products and 3 sums (u times |operands| <= 2M, 2M, 3M,
        /// M, M); s and t rounded to f32 (|df/ds| <= 2M, |df/dt| <= 4M times u). About 22 u M;
        /// asserted at 32 u M.
        #[test]
        fn gouraud_is_exact_for_linear_functions(
            sels in prop::collection::vec(any::<u32>(), 0..40),
            a in -2.0f64..2.0, b in -2.0f64..2.0, c in -2.0f64..2.0,
        ) {
            let corners = [
                DVec3::new(0.1, 0.1, 0.0),
                DVec3::new(0.8, 0.2, 0.0),
                DVec3::new(0.95, 0.9, 0.0),
                DVec3::new(0.25, 0.8, 0.0),
            ];
            let f = |u: f64, v: f64| DVec3::new(a + b * u + c * v, 1.0 - a * u, b * v - c);
            let sq = SampledQuadtree::from_fn(grow(&sels, 6), |u, v| f(u, v).as_vec3());
            let scene = scene_of(corners, 16);
            let mesh = MeshModel::build(&scene, std::slice::from_ref(&sq)).unwrap();
            let m = sq.values.iter().map(|v| v.abs().max_element()).fold(0.0f32, f32::max) as f64;
            let n = 23;
            for j in 0..=n {
                for i in 0..=n {
                    let p = [i as f64 / n as f64, j as f64 / n as f64];
                    let (k, (s, t)) = mesh
                        .parent_uv
                        .iter()
                        .enumerate()
                        .find_map(|(k, tri)| local_st(tri, p).map(|st| (k, st)))
                        .unwrap();
                    let got = mesh.patch(k).eval(s as f32, t as f32).as_dvec3();
                    let err = (got - f(p[0], p[1])).abs().max_element();
                    prop_assert!(err <= 32.0 * U32 * m, "at {:?}: err {}", p, err);
                }
            }
            check_vertex_colours(&mesh, std::slice::from_ref(&sq));
        }
    }
}
