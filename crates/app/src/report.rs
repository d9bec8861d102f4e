//! Human-readable summaries of pipeline inputs, for `pixelflow-sim check`.
//!
//! A [`SceneSummary`] is computed from a validated [`Scene`] and holds only counts and sizes, so
//! it is cheap, deterministic and prints the same table for the same file. Its memory estimate
//! is a range, not a promise: the adaptive solve's memory depends on how deep each quadtree
//! actually refines, which only the solve knows. The range brackets it between every quadtree
//! at its starting depth and every quadtree refined uniformly to `max_depth`
//! (`crate::budget::solve_estimate`, the estimator the jobs check against the memory
//! limit), which is what a user needs to see before a run that would not fit;
//! [`budget_text`] adds the frame, textures and mesh against the limit.

use glam::DVec3;
use scene::{Scene, Shape};
use std::fmt;

/// Counts and sizes of a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSummary {
    /// The file the scene came from.
    pub source: String,
    /// Image size in pixels.
    pub image: (u32, u32),
    /// `perspective, fov_y 39.3 deg` or `orthographic 1 x 1`.
    pub projection: String,
    /// All polygons.
    pub polygons: usize,
    /// Polygons that are triangles.
    pub triangles: usize,
    /// Polygons that are quads.
    pub quads: usize,
    /// Polygons that receive light by their vertex normals (a surface the model marks smooth).
    pub smooth: usize,
    /// Materials.
    pub materials: usize,
    /// Polygons with an emitting material.
    pub emitters: usize,
    /// Spot lights.
    pub spots: usize,
    /// Inline polygons and OBJ groups.
    pub objects: usize,
    /// Axis-aligned bounds (min, max) of polygon corners and spot positions.
    pub bounds: (DVec3, DVec3),
    /// Sum of polygon areas, square scene units.
    pub total_area: f64,
    /// Total emitted power of the emitting polygons, emission x area summed over the three
    /// channels (W).
    pub emitted_power: f64,
    /// Radiosity quadtree depths (min, max).
    pub depths: (u32, u32),
    /// Estimated solve memory in bytes with every quadtree at its starting depth (`min_depth`,
    /// or its shooter patches' depth if deeper): quadtrees, samples, pair tables, shooters.
    pub memory_min: u64,
    /// The same with every quadtree uniformly at `max_depth`.
    pub memory_max: u64,
    /// Shared polygon edges ([`scene::adjacency`]).
    pub adjacency: scene::adjacency::AdjacencySummary,
    /// Seams the reconstruction joins C1 (coplanar) and C0 (gentle folds, slanted sides), and
    /// those it leaves
    /// apart because a polygon stands on them or because their lattices or shapes do not line
    /// up ([`reconstruction::seam`]).
    pub seams: (usize, usize, usize, usize),
    /// Contact lines ([`scene::contact`]): how many, how long in all, the polygons they cut
    /// and the pieces those became, and where (the first few cut polygons' origins with their
    /// lines).
    pub contacts: String,
    /// Triangle pairs the loader merged into quads ([`scene::triangle_pairs`]), and whether it
    /// looked for them.
    pub merged: (usize, bool),
    /// Warnings the loader emitted.
    pub warnings: usize,
    /// Notes the loader emitted (repairs that change nothing the image shows).
    pub notes: usize,
}

/// The `contact lines` line of `check`: the lines, what they cut, and where (up to three
/// polygons, by the file and line they were written at).
fn contacts_text(scene: &Scene) -> String {
    let c = &scene.contacts;
    if c.lines.is_empty() {
        return if scene.radiosity.cut_contacts {
            "0".to_string()
        } else {
            "not looked for (radiosity.cut_contacts = false)".to_string()
        };
    }
    let (cut, pieces) = c.counts();
    let mut t = format!(
        "{} ({:.4} long in all) cut {cut} polygons into {pieces} pieces",
        c.lines.len(),
        c.length()
    );
    let mut at = Vec::new();
    for (&(orig, _), place) in c.pieces.iter().zip(&c.places) {
        let lines = c.lines.iter().filter(|l| l.receiver == orig).count();
        at.push(format!("{place} ({lines} lines)"));
    }
    let more = at.len().saturating_sub(3);
    if !at.is_empty() {
        t += &format!(
            ": {}",
            at.into_iter().take(3).collect::<Vec<_>>().join(", ")
        );
    }
    if more > 0 {
        t += &format!(" and {more} more");
    }
    if c.skipped > 0 {
        t += &format!(
            "; {} lines not cut along (more than {} on one polygon)",
            c.skipped,
            scene::contact::MAX_LINES
        );
    }
    t
}

/// Summarises `scene`.
pub fn summarize(scene: &Scene) -> SceneSummary {
    let triangles = scene
        .polygons
        .iter()
        .filter(|p| p.shape == Shape::Triangle)
        .count();
    let mut total_area = 0.0;
    let mut emitted_power = 0.0;
    for (i, p) in scene.polygons.iter().enumerate() {
        total_area += p.area;
        let m = scene.material_of(i);
        emitted_power += p.area * m.emission.element_sum();
    }
    let projection = match scene.camera.projection {
        scene::Projection::Perspective { fov_y_deg } => {
            format!("perspective, fov_y {fov_y_deg:.2} deg")
        }
        scene::Projection::Orthographic { width, height } => {
            format!("orthographic, {width} x {height}")
        }
    };
    let (start, worst) = crate::budget::solve_estimate(scene);
    let adjacency = scene.adjacency();
    let seams = reconstruction::Seams::of_scene(scene);
    SceneSummary {
        source: scene.source.display().to_string(),
        image: (scene.width, scene.height),
        projection,
        polygons: scene.polygons.len(),
        triangles,
        quads: scene.polygons.len() - triangles,
        smooth: scene
            .polygons
            .iter()
            .filter(|p| p.shading.is_some())
            .count(),
        materials: scene.materials.len(),
        emitters: scene.emitter_count(),
        spots: scene.spots.len(),
        objects: scene.objects.len(),
        bounds: scene.bounds(),
        total_area,
        emitted_power,
        depths: (scene.radiosity.min_depth, scene.radiosity.max_depth),
        memory_min: start.total(),
        memory_max: worst,
        adjacency: adjacency.summary(&scene.polygons, &scene.materials),
        seams: (
            seams.joined() - seams.folds() - seams.slanted(),
            seams.folds() + seams.slanted(),
            seams.standing(),
            seams.unjoined(),
        ),
        contacts: contacts_text(scene),
        merged: (scene.merged.pairs, scene.radiosity.merge_triangles),
        warnings: scene.warnings.len(),
        notes: scene.notes.len(),
    }
}

pub use base::error::human_bytes;

fn v3(v: DVec3) -> String {
    format!("({:.4}, {:.4}, {:.4})", v.x, v.y, v.z)
}

impl fmt::Display for SceneSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rows: Vec<(&str, String)> = vec![
            ("scene", self.source.clone()),
            ("image", format!("{} x {}", self.image.0, self.image.1)),
            ("camera", self.projection.clone()),
            (
                "polygons",
                format!(
                    "{} ({} quads, {} triangles){}{}",
                    self.polygons,
                    self.quads,
                    self.triangles,
                    match self.smooth {
                        0 => String::new(),
                        n => format!("; {n} smooth (shaded by their vertex normals)"),
                    },
                    match self.merged {
                        (0, true) => String::new(),
                        (n, true) => format!("; {n} triangle pairs merged into quads"),
                        (_, false) => "; triangle pairs not merged \
                                       (radiosity.merge_triangles = false)"
                            .to_string(),
                    }
                ),
            ),
            ("objects", self.objects.to_string()),
            ("materials", self.materials.to_string()),
            ("emitters", format!("{} polygons", self.emitters)),
            ("spot lights", self.spots.to_string()),
            ("emitted power", format!("{:.4} W", self.emitted_power)),
            ("bounds min", v3(self.bounds.0)),
            ("bounds max", v3(self.bounds.1)),
            ("total area", format!("{:.4}", self.total_area)),
            (
                "quadtree depth",
                format!("{} ..= {}", self.depths.0, self.depths.1),
            ),
            (
                "solve memory",
                format!(
                    "{} (at the starting depth) .. {} (all at max depth)",
                    human_bytes(self.memory_min),
                    human_bytes(self.memory_max)
                ),
            ),
            ("contact lines", self.contacts.clone()),
            ("shared edges", adjacency_text(&self.adjacency)),
            (
                "seams",
                format!(
                    "{} joined C1 and {} joined C0 (gentle folds, slanted sides) unless their \
                     samples disagree, apart: {} with a polygon standing on them, {} whose \
                     lattices do not line up or that are slivers",
                    self.seams.0, self.seams.1, self.seams.2, self.seams.3
                ),
            ),
            ("warnings", self.warnings.to_string()),
            ("notes", self.notes.to_string()),
        ];
        for (k, v) in rows {
            writeln!(f, "{k:<15} {v}")?;
        }
        Ok(())
    }
}

/// The `shared edges` line: how polygons meet, and what the reconstruction joins.
fn adjacency_text(a: &scene::adjacency::AdjacencySummary) -> String {
    let mut t = format!(
        "{} ({} coplanar, {} of them one material; {} creases, {} folded; {} T-junctions)",
        a.shared, a.coplanar, a.continuous, a.creases, a.folded, a.partial
    );
    if a.largest_gap > 0.0 {
        t += &format!(", largest gap {:.1e} of an edge", a.largest_gap);
    }
    if a.near_misses > 0 {
        t += &format!(
            "; {} near misses (sides within {} of an edge's length, not joined)",
            a.near_misses,
            scene::adjacency::NEAR_EDGE
        );
    }
    t
}

/// The memory estimate of a scene ([`crate::budget::scene_budget`]) against `limit`, for
/// `check`: the solve (at its starting depth, and the worst case), a frame at the scene's image
/// size, the textures and the mesh at the worst case (every quadtree as deep as it can refine).
pub fn budget_text(scene: &Scene, budget: &crate::budget::SceneBudget, limit: u64) -> String {
    let b = budget;
    let limit_text = if limit == u64::MAX {
        "none".to_string()
    } else {
        human_bytes(limit)
    };
    let rows = [
        ("memory limit", limit_text),
        (
            "solve at start",
            format!("{} ({})", human_bytes(b.solve.total()), b.solve.detail()),
        ),
        ("solve, worst", human_bytes(b.solve_worst)),
        (
            "past guards",
            format!(
                "at most {} nodes per polygon, {} in all (near small lights, cone edges, \
                 peaks; stopped by the memory limit first)",
                radiosity::sizes::DIVE_NODES,
                human_bytes(crate::budget::dive_bytes(scene))
            ),
        ),
        (
            "frame",
            format!(
                "{} ({} x {}, aa {}, renderers {}, PNG)",
                human_bytes(b.frame.total()),
                scene.width,
                scene.height,
                scene.render.aa_samples.samples(),
                b.renderers
            ),
        ),
        ("textures, worst", human_bytes(b.textures_worst)),
        ("mesh, worst", human_bytes(b.mesh_worst)),
        (
            "verdict",
            if b.check(limit).is_err() {
                "over the limit: a solve or render would be refused".to_string()
            } else if b.solve_worst > limit {
                "fits at the start; a solve refining far toward max_depth would be stopped"
                    .to_string()
            } else {
                "fits".to_string()
            },
        ),
    ];
    let mut t = String::new();
    for (k, v) in rows {
        t += &format!("{k:<15} {v}\n");
    }
    t
}

/// Decimal megabytes (10^6 bytes), as Table 1 prints sizes.
fn mb(bytes: u64) -> f64 {
    bytes as f64 / 1e6
}

/// Thousands separators: 158670 -> "158,670".
pub fn grouped(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, ch) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(ch);
    }
    out
}

/// The `stats` table for one scene: the paper's Table 1 columns (original, mesh and RAT models,
/// sizes, texture memory and count) plus the RRP memory, and the measured frame times with the
/// ratios the project tracks (direct / bilinear, direct / bicubic, mesh / direct).
pub fn model_stats_text(s: &crate::commands::stats::ModelStats) -> String {
    let mut t = format!("{}: {} radiosity samples\n", s.scene, grouped(s.samples));
    if let Some(level) = lanes::Level::named(s.simd) {
        t += &format!("simd build: {}\n", level.describe());
    }
    t += "model            triangles    vertices   size (MB)\n";
    t += &format!(
        "original      {:>12} {:>11} {:>11.3}\n",
        grouped(s.original.triangles),
        grouped(s.original.vertices),
        mb(s.original.bytes)
    );
    t += &format!(
        "mesh (poly)   {:>12} {:>11} {:>11.3}   ({} T-vertices)\n",
        grouped(s.mesh.triangles),
        grouped(s.mesh.vertices),
        mb(s.mesh.bytes),
        grouped(s.mesh.t_vertices)
    );
    t += &format!(
        "RAT           {:>12} {:>11} {:>11.3}\n",
        grouped(s.rat_triangles),
        grouped(s.rat_vertices),
        mb(s.rat_bytes)
    );
    t += &memory_lines(s);
    t += &guard_line(&s.guard_stops);
    t += &frame_lines(&s.frames);
    t
}

/// The texture and RRP memory lines of [`model_stats_text`].
fn memory_lines(s: &crate::commands::stats::ModelStats) -> String {
    let mut t = String::new();
    let m = &s.texture_memory;
    t += &format!(
        "texture memory: {} textures, {} texels; {:.3} / {:.3} / {:.3} MB at 8 / 12 / 32 bits \
         per channel ({:.3} / {:.3} / {:.3} MB with mip chains)\n",
        grouped(m.textures as u64),
        grouped(m.texels),
        mb(m.bytes[0]),
        mb(m.bytes[1]),
        mb(m.bytes[2]),
        mb(m.bytes_with_chain[0]),
        mb(m.bytes_with_chain[1]),
        mb(m.bytes_with_chain[2]),
    );
    t += &format!(
        "RRP memory: {} patches; stored {:.3} MB (trees and f32 samples, derivatives estimated \
         on load), compact (held) {:.3} MB, expanded {:.3} MB; patch caches {:.3} MB; the held \
         Hermite data quantized to 16 bits would take {:.3} MB (measured, not stored)\n",
        grouped(s.rrp_patches),
        mb(s.rrp_stored_bytes),
        mb(s.rrp_bytes),
        mb(s.rrp_expanded_bytes),
        mb(s.rrp_cache_bytes),
        mb(s.rrp_encoded_bytes)
    );
    t
}

/// The guard stops line of [`model_stats_text`].
fn guard_line(g: &crate::commands::stats::GuardReport) -> String {
    match &g.worst {
        Some(at) => format!(
            "guard stops: {} leaves split to max_depth with the error test still failing, \
             which may misplace up to {:.2} % of the light the scene reflects, worst at {at} \
             ({:.1} % of its level); {} more only for a shadow boundary, {} at a spot's cone \
             edge\n",
            grouped(g.leaves),
            100.0 * g.error_share,
            100.0 * g.worst_excess,
            grouped(g.shadow_leaves),
            grouped(g.edge_leaves)
        ),
        None => format!(
            "guard stops: none with the error test failing; {} leaves only for a shadow \
             boundary, {} at a spot's cone edge\n",
            grouped(g.shadow_leaves),
            grouped(g.edge_leaves)
        ),
    }
}

/// The frame times and ratios of [`model_stats_text`] (nothing without frames).
fn frame_lines(frames: &[crate::commands::bench::BenchRow]) -> String {
    let mut t = String::new();
    let Some(r0) = frames.first() else {
        return t;
    };
    t += &format!(
        "frame times at {} x {}, AA {}, median of {} frames:\n",
        r0.width, r0.height, r0.aa, r0.frames
    );
    for r in frames {
        t += &format!(
            "  {:<17} {:>9.2} ms {:>8.1} fps   (raster {:.2} ms, shading {:.2} ms)\n",
            r.method, r.frame_ms, r.fps, r.raster_ms, r.shading_ms
        );
    }
    let ms = |name: &str| frames.iter().find(|r| r.method == name).map(|r| r.frame_ms);
    let ratio = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) if b > 0.0 => format!("{:.2}", a / b),
        _ => "-".into(),
    };
    let (d, bl, bc, me) = (
        ms("direct"),
        ms("texture-bilinear"),
        ms("texture-bicubic"),
        ms("mesh"),
    );
    t += &format!(
        "  ratios: direct/bilinear {}, direct/bicubic {}, mesh/direct {}\n",
        ratio(d, bl),
        ratio(d, bc),
        ratio(me, d)
    );
    t
}

/// The lines `export` prints: what was written, its size and, for a lightmap, how well the
/// atlas packs and how densely it samples the polygons.
pub fn export_text(r: &export::ExportReport) -> String {
    let mut t = format!(
        "{} export: {} polygons, {} triangles, {} vertices, exposure {:+}\n",
        r.kind,
        grouped(r.polygons as u64),
        grouped(r.triangles as u64),
        grouped(r.vertices as u64),
        r.exposure
    );
    if let Some(a) = &r.atlas {
        t += &format!(
            "atlas: {} page(s), {} texels; charts with gutters fill {:.1} % of them (packing), \
             the polygons' own texels {:.1} % (utilization)\n",
            a.pages,
            grouped(a.page_texels),
            100.0 * a.packing,
            100.0 * a.utilization
        );
        t += &format!(
            "texel density: {:.3} / {:.3} / {:.3} texels per scene unit (least / median / greatest)\n",
            a.texels_per_unit[0], a.texels_per_unit[1], a.texels_per_unit[2]
        );
        t += &format!(
            "largest texel shift of the triangulation: {:.3} texel widths\n",
            r.largest_shift_texels
        );
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_of_a_small_scene() {
        // A 2 x 1 quad lit by a 1 x 1 emitting triangle (area 0.5) and a spot.
        let text = r#"
            [camera]
            eye = [1, 0.5, 3]
            look_at = [1, 0.5, 0]
            fov_y = 40
            [[materials]]
            name = "w"
            reflectance = [0.5, 0.5, 0.5]
            [[materials]]
            name = "e"
            reflectance = [0.5, 0.5, 0.5]
            emission = [1, 2, 3]
            [[polygons]]
            vertices = [[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]
            material = "w"
            [[polygons]]
            vertices = [[0, 0, 1], [0, 1, 1], [1, 1, 1]]
            material = "e"
            [[spots]]
            position = [1, 4, 1]
            direction = [0, -1, 0]
            intensity = [1, 1, 1]
            half_angle = 30
            [radiosity]
            min_depth = 1
            max_depth = 3
        "#;
        let scene = scene::parse_scene(text, std::path::Path::new("s.toml")).unwrap();
        let s = summarize(&scene);
        assert_eq!((s.polygons, s.quads, s.triangles), (2, 1, 1));
        assert_eq!((s.materials, s.emitters, s.spots, s.objects), (2, 1, 1, 2));
        assert_eq!(s.bounds, (DVec3::ZERO, DVec3::new(2.0, 4.0, 1.0)));
        assert!((s.total_area - 2.5).abs() < 1e-15);
        // Emission (1 + 2 + 3) over area 0.5.
        assert!((s.emitted_power - 3.0).abs() < 1e-15);
        // Shooter patches: a patch holds at most 1/16 of the total area 2.5, so the quad (area
        // 2) starts at depth 2 (16 patches of 0.125) and the triangle (0.5) at depth 1 (4 of
        // 0.125), min_depth 1 being shallower: 21 + 5 nodes, 25 + 9 samples. Uniform trees of
        // depth d: (4^(d+1) - 1) / 3 nodes, (2^d + 1)^2 samples. Shooters: the spot, the
        // emitter, 16 + 4 patches = 22, each with a pair entry per polygon; sample points:
        // the emitter's `shadow_rays` and a quarter of them per patch. RRP build: one patch
        // per leaf (16 + 4 leaves at the start). Coarse points: the quad's depth-3 grid (81)
        // and the triangle's depth-2 grid (25), 4 B per shooter and point.
        use radiosity::sizes::state_bytes;
        use radiosity::sizes::PAIR_BYTES;
        let patch = std::mem::size_of::<reconstruction::PatchCoeffs>() as u64;
        let rays = u64::from(scene.radiosity.shadow_rays);
        // Exact visibility (44 pairs): an entry and an index slot per pair.
        let pairs = 22 * 2 * (PAIR_BYTES + 8);
        let points = (rays + 20 * rays.div_ceil(4)) * 24;
        let cache = 4 * 22 * (81 + 25);
        assert_eq!(
            s.memory_min,
            state_bytes(21 + 5, 25 + 9) + 20 * patch + cache + pairs + points
        );
        // Worst case: leaves stop splitting at the smallest element size, the bounds' diagonal
        // sqrt(2^2 + 4^2 + 1^2) = 4.58 over 2^max_depth = 0.573; the quad's longest edge 2
        // halves to 0.5 at depth 2, the triangle's sqrt(2) to 0.354 at depth 2: both depth 2,
        // not max_depth 3.
        assert_eq!(
            s.memory_max,
            state_bytes(2 * 21, 2 * 25) + 32 * patch + cache + pairs + points
        );
        let table = s.to_string();
        assert!(
            table.contains("polygons        2 (1 quads, 1 triangles)\n"),
            "{table}"
        );
        assert!(
            table.contains("camera          perspective, fov_y 40.00 deg\n"),
            "{table}"
        );
        assert!(table.contains("shared edges    "), "{table}");
        assert_eq!(
            s.adjacency.shared,
            s.adjacency.coplanar + s.adjacency.creases + s.adjacency.folded
        );
        assert!(table.contains("contact lines   0\n"), "{table}");
        assert_eq!(table.lines().count(), 19);
    }

    #[test]
    fn bytes_are_human() {
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(1536), "1.5 KiB");
        assert_eq!(human_bytes(3 << 30), "3.0 GiB");
    }
}
