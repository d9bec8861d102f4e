//! Human-readable summaries of pipeline inputs, for `pixelflow-sim check`.
//!
//! A [`SceneSummary`] is computed from a validated [`Scene`] and holds only counts and sizes, so
//! it is cheap, deterministic and prints the same table for the same file. Its memory estimate
//! is a range, not a promise: the adaptive solve's memory depends on how deep each quadtree
//! actually refines, which only the solve knows. The range brackets it between every quadtree
//! stopping at `min_depth` and every quadtree refined uniformly to `max_depth` (see
//! [`quadtree_bytes`]), which is what a user needs to see before a run that would not fit.

use crate::quadtree::{Node, VertexKey};
use crate::scene::{Scene, Shape};
use glam::DVec3;
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
    /// Estimated solve memory in bytes with every quadtree at `min_depth`.
    pub memory_min: u64,
    /// Estimated solve memory in bytes with every quadtree uniformly at `max_depth`.
    pub memory_max: u64,
    /// Warnings the loader emitted.
    pub warnings: usize,
}

/// Bytes one polygon's solution takes when its quadtree is refined uniformly to `depth`.
///
/// A uniform tree of depth d has (4^(d+1) - 1) / 3 nodes ([`Node`] each) and (2^d + 1)^2 vertices,
/// each sampled once ([`VertexKey`] plus an RGB `f32` sample, as in
/// [`crate::quadtree::SampledQuadtree`]). Saturates instead of overflowing.
pub fn quadtree_bytes(depth: u32) -> u64 {
    let d = depth.min(30);
    let nodes = ((1u64 << (2 * d + 2)) - 1) / 3;
    let side = (1u64 << d) + 1;
    let vertices = side * side;
    let node_bytes = std::mem::size_of::<Node>() as u64;
    let vertex_bytes = (std::mem::size_of::<VertexKey>() + 3 * std::mem::size_of::<f32>()) as u64;
    nodes
        .saturating_mul(node_bytes)
        .saturating_add(vertices.saturating_mul(vertex_bytes))
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
        crate::scene::Projection::Perspective { fov_y_deg } => {
            format!("perspective, fov_y {fov_y_deg:.2} deg")
        }
        crate::scene::Projection::Orthographic { width, height } => {
            format!("orthographic, {width} x {height}")
        }
    };
    let n = scene.polygons.len() as u64;
    SceneSummary {
        source: scene.source.display().to_string(),
        image: (scene.width, scene.height),
        projection,
        polygons: scene.polygons.len(),
        triangles,
        quads: scene.polygons.len() - triangles,
        materials: scene.materials.len(),
        emitters: scene.emitter_count(),
        spots: scene.spots.len(),
        objects: scene.objects.len(),
        bounds: scene.bounds(),
        total_area,
        emitted_power,
        depths: (scene.radiosity.min_depth, scene.radiosity.max_depth),
        memory_min: n.saturating_mul(quadtree_bytes(scene.radiosity.min_depth)),
        memory_max: n.saturating_mul(quadtree_bytes(scene.radiosity.max_depth)),
        warnings: scene.warnings.len(),
    }
}

/// `1.5 MiB` style.
pub fn human_bytes(b: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut x = b as f64;
    let mut u = 0;
    while x >= 1024.0 && u + 1 < UNITS.len() {
        x /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{x:.1} {}", UNITS[u])
    }
}

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
                    "{} ({} quads, {} triangles)",
                    self.polygons, self.quads, self.triangles
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
                    "{} (all at min depth) .. {} (all at max depth)",
                    human_bytes(self.memory_min),
                    human_bytes(self.memory_max)
                ),
            ),
            ("warnings", self.warnings.to_string()),
        ];
        for (k, v) in rows {
            writeln!(f, "{k:<15} {v}")?;
        }
        Ok(())
    }
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
pub fn model_stats_text(s: &crate::jobs::stats::ModelStats) -> String {
    let mut t = format!("{}: {} radiosity samples\n", s.scene, grouped(s.samples));
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
        "RRP memory: {} patches; compact (held) {:.3} MB, encoded {:.3} MB, samples alone \
         {:.3} MB, expanded {:.3} MB; patch caches {:.3} MB\n",
        grouped(s.rrp_patches),
        mb(s.rrp_bytes),
        mb(s.rrp_encoded_bytes),
        mb(s.rrp_samples_bytes),
        mb(s.rrp_expanded_bytes),
        mb(s.rrp_cache_bytes)
    );
    if let Some(r0) = s.frames.first() {
        t += &format!(
            "frame times at {} x {}, AA {}, median of {} frames:\n",
            r0.width, r0.height, r0.aa, r0.frames
        );
        for r in &s.frames {
            t += &format!(
                "  {:<17} {:>9.2} ms {:>8.1} fps   (raster {:.2} ms, shading {:.2} ms)\n",
                r.method, r.frame_ms, r.fps, r.raster_ms, r.shading_ms
            );
        }
        let ms = |name: &str| {
            s.frames
                .iter()
                .find(|r| r.method == name)
                .map(|r| r.frame_ms)
        };
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
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_tree_sizes() {
        let node = std::mem::size_of::<Node>() as u64;
        let vert = (std::mem::size_of::<VertexKey>() + 12) as u64;
        // Depth 0: the root and its 4 corners.
        assert_eq!(quadtree_bytes(0), node + 4 * vert);
        // Depth 2: 1 + 4 + 16 nodes and a 5 x 5 vertex grid.
        assert_eq!(quadtree_bytes(2), 21 * node + 25 * vert);
        assert!(quadtree_bytes(30) > quadtree_bytes(16));
    }

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
        let scene = crate::scene::parse_scene(text, std::path::Path::new("s.toml")).unwrap();
        let s = summarize(&scene);
        assert_eq!((s.polygons, s.quads, s.triangles), (2, 1, 1));
        assert_eq!((s.materials, s.emitters, s.spots, s.objects), (2, 1, 1, 2));
        assert_eq!(s.bounds, (DVec3::ZERO, DVec3::new(2.0, 4.0, 1.0)));
        assert!((s.total_area - 2.5).abs() < 1e-15);
        // Emission (1 + 2 + 3) over area 0.5.
        assert!((s.emitted_power - 3.0).abs() < 1e-15);
        assert_eq!(s.memory_min, 2 * quadtree_bytes(1));
        assert_eq!(s.memory_max, 2 * quadtree_bytes(3));
        let table = s.to_string();
        assert!(
            table.contains("polygons        2 (1 quads, 1 triangles)\n"),
            "{table}"
        );
        assert!(
            table.contains("camera          perspective, fov_y 40.00 deg\n"),
            "{table}"
        );
        assert_eq!(table.lines().count(), 15);
    }

    #[test]
    fn bytes_are_human() {
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(1536), "1.5 KiB");
        assert_eq!(human_bytes(3 << 30), "3.0 GiB");
    }
}
