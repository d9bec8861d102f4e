//! A curved wall modelled as facets with vertex normals, end to end through the OBJ loader: a
//! quarter cylinder (radius 1, height 1) of 8 or 32 facets facing its axis, under an area light
//! inside it. With the model's `vn` the facets receive light as the smooth surface does
//! (`scene::shading`), the reconstruction joins their gentle folds, and the light does not step
//! at the creases; the same wall without normals (flat facets) steps by about the facets' angle
//! times the light's slope in angle. The step is read from the RRPs on either side of every
//! crease, against the local light (the mean of the two sides). Run with `--nocapture` for
//! the numbers.

use std::path::{Path, PathBuf};

use app::context::Context;
use app::context::TextureOptions;
use app::prepare::prepare_path;

/// How the wall's OBJ marks its surface.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Marked {
    /// Every face corner names the cylinder's `vn` (pointing at the axis).
    Normals,
    /// No face names a `vn`, but the faces are in smoothing group 1 (`s 1`).
    Group,
    /// Flat: `s off`, and no face names a `vn` (the file still lists them, which tobj would
    /// hand out to faces without any).
    Flat,
}

/// Writes the scene and its OBJ into `dir`.
fn write_wall(dir: &Path, facets: usize, marked: Marked) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let s = if marked == Marked::Group { "1" } else { "off" };
    let mut obj = format!("o wall\ns {s}\n");
    for k in 0..=facets {
        let t = std::f64::consts::FRAC_PI_2 * k as f64 / facets as f64;
        let (c, s) = (t.cos(), t.sin());
        obj += &format!("v {c} 0 {s}\nv {c} 1 {s}\nvn {} 0 {}\n", -c, -s);
    }
    for k in 0..facets {
        // Corners (bottom k, bottom k+1, top k+1, top k): counter-clockwise from the axis.
        let (b0, t0, b1, t1) = (2 * k + 1, 2 * k + 2, 2 * k + 3, 2 * k + 4);
        let (n0, n1) = (k + 1, k + 2);
        if marked == Marked::Normals {
            obj += &format!("f {b0}//{n0} {b1}//{n1} {t1}//{n1} {t0}//{n0}\n");
        } else {
            obj += &format!("f {b0} {b1} {t1} {t0}\n");
        }
    }
    std::fs::write(dir.join("wall.obj"), obj).unwrap();
    let toml = r#"
[camera]
eye = [-1.0, 0.5, -1.0]
look_at = [0.5, 0.5, 0.5]
fov_y = 60.0

[image]
width = 32
height = 32

[[materials]]
name = "white"
reflectance = [0.6, 0.6, 0.6]

[[materials]]
name = "light"
reflectance = [0.0, 0.0, 0.0]
emission = [4.0, 4.0, 4.0]

[[obj]]
file = "wall.obj"
default_material = "white"

# A square light 0.2 wide at the height of the wall's middle, facing the wall's middle facet.
[[polygons]]
name = "light"
material = "light"
vertices = [[0.2, 0.4, 0.341], [0.341, 0.4, 0.2], [0.341, 0.6, 0.2], [0.2, 0.6, 0.341]]
"#;
    let path = dir.join("wall.toml");
    std::fs::write(&path, toml).unwrap();
    path
}

/// Largest step of the light across the creases, relative to the local light, over points
/// along each crease; and the number of facets that carry a shading frame.
fn crease_steps(facets: usize, marked: Marked) -> (f64, usize) {
    let (step, shaded, _) = creases(facets, marked);
    (step, shaded)
}

/// [`crease_steps`], and the local light at the middle of every crease (the mean of its two
/// sides at half height), in order of angle.
fn creases(facets: usize, marked: Marked) -> (f64, usize, Vec<f64>) {
    let dir = std::env::temp_dir().join(format!(
        "pfs-smooth-{}-{facets}-{marked:?}",
        std::process::id()
    ));
    let path = write_wall(&dir, facets, marked);
    let p = prepare_path(&Context::default(), &path, &TextureOptions::default()).unwrap();
    let (rec, _) = p.expanded().unwrap();
    // The facets in order of angle about the axis.
    let mut walls: Vec<usize> = (0..p.scene.polygons.len())
        .filter(|&i| p.scene.material_of(i).emission.max_element() == 0.0)
        .collect();
    let angle = |i: usize| {
        let c = p.scene.polygons[i].centroid();
        c.z.atan2(c.x)
    };
    walls.sort_by(|&a, &b| angle(a).total_cmp(&angle(b)));
    assert_eq!(walls.len(), facets);
    let shaded = walls
        .iter()
        .filter(|&&i| p.scene.polygons[i].shading.is_some())
        .count();
    let mut worst = 0.0f64;
    let mut middles = Vec::new();
    for pair in walls.windows(2) {
        let (a, b) = (pair[0] as u32, pair[1] as u32);
        // Facet a's side u = 1 is facet b's side u = 0 (v runs up both).
        for j in 1..20 {
            let v = j as f32 / 20.0;
            let (la, lb) = (rec.eval(a, 1.0, v).x as f64, rec.eval(b, 0.0, v).x as f64);
            let local = 0.5 * (la + lb);
            assert!(local > 0.0, "crease {a}-{b} unlit at v = {v}");
            worst = worst.max((la - lb).abs() / local);
        }
        let (la, lb) = (
            rec.eval(a, 1.0, 0.5).x as f64,
            rec.eval(b, 0.0, 0.5).x as f64,
        );
        middles.push(0.5 * (la + lb));
    }
    let _ = std::fs::remove_dir_all(&dir);
    (worst, shaded, middles)
}

#[test]
fn a_faceted_cylinder_with_vertex_normals_does_not_step_at_its_creases() {
    for facets in [8, 32] {
        let (smooth, shaded) = crease_steps(facets, Marked::Normals);
        // Smoothing groups at one facet count: the same frames as the normals give.
        let (grouped, grouped_shaded) = if facets == 32 {
            crease_steps(facets, Marked::Group)
        } else {
            (smooth, shaded)
        };
        let (flat, none) = crease_steps(facets, Marked::Flat);
        eprintln!(
            "{facets} facets: crease step {:.3} % of the local light with vn, {:.3} % with a \
             smoothing group, {:.3} % flat",
            100.0 * smooth,
            100.0 * grouped,
            100.0 * flat
        );
        assert_eq!(shaded, facets, "every facet has its vertex normals");
        assert_eq!(
            grouped_shaded, facets,
            "every facet has its group's normals"
        );
        assert_eq!(none, 0, "no facet of the flat wall has a frame");
        // The flat facets' step is the change of the cosine over a facet's angle (90 / n
        // degrees): several percent at 8 facets, about 1 % at 32, far above the smooth wall's.
        assert!(flat > 0.005, "the flat wall steps: {flat}");
        for (how, step) in [("vn", smooth), ("s 1", grouped)] {
            assert!(step <= 0.005, "{facets} facets, {how}: step {step}");
            assert!(
                step < 0.25 * flat,
                "{facets}, {how}: {step} against {flat} flat"
            );
        }
    }
}

/// The smooth facets' light is the curved wall's: at the 32-facet wall's creases (points of the
/// true cylinder) it matches a flat wall of 128 facets (whose creases include those points;
/// its facets turn by 0.7 degrees, and the mean of a crease's two sides cancels the step to
/// first order) to 1 %.
#[test]
fn smooth_facets_receive_the_light_of_the_curved_surface() {
    let (_, _, coarse) = creases(32, Marked::Normals);
    let (_, _, fine) = creases(128, Marked::Flat);
    let mut worst = 0.0f64;
    for (k, c) in coarse.iter().enumerate() {
        let f = fine[4 * k + 3];
        worst = worst.max((c - f).abs() / f);
    }
    eprintln!(
        "32 smooth facets against 128 flat ones: worst {:.3} %",
        100.0 * worst
    );
    assert!(worst <= 0.01, "worst {worst}");
}
