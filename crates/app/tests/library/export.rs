//! glTF export, read back with the `gltf` crate: every polygon present with its corners, every
//! lightmap coordinate inside its polygon's chart, and the re-imported atlas drawn with the
//! project's own texture-bilinear rasterizer reproducing `render --method texture-bilinear`:
//! exactly (to f32 roundings of the gutters) from the linear pages, within one 8-bit level on
//! 99.9 % of pixels from the PNG pages (their own 8-bit rounding, before a second one).

use app::prepare::Prepared;
use base::method::{Filter, Method};
use engine::frame::{render, FrameOptions};
use engine::shading::Shader;
use export::readback::{read, Pages};
use export::{export_lightmap, export_mesh};
use imageio::write::to_srgb8;
use scene::Scene;

fn draw(scene: &Scene, set: &reconstruction::texture::TextureSet) -> Vec<glam::Vec3> {
    let opts = FrameOptions::new(160, 120);
    let shader = Shader::Texture {
        set,
        filter: Filter::Bilinear,
        anisotropy: 1,
    };
    render(
        scene,
        &scene.camera,
        &shader,
        Method::Texture(Filter::Bilinear),
        &opts,
    )
    .expect("renders")
    .pixels
}

fn round_trip(name: &str, p: &Prepared, container: &str) {
    let dir = tempdir(name);
    let out = dir.join(format!("{name}.{container}"));
    let (set, _) = p.textures().unwrap();
    let exposure = p.scene.display.exposure;
    let outputs = base::output::Outputs::new();
    let report = export_lightmap(
        &p.scene,
        set,
        p.expanded().unwrap().0,
        4096,
        exposure,
        &out,
        &outputs,
    )
    .unwrap();
    assert!(
        report.files.iter().all(|f| f.is_file()),
        "{:?}",
        report.files
    );
    let a = report.atlas.unwrap();
    assert!(a.packing > 0.0 && a.packing <= 1.0 && a.utilization <= a.packing);
    assert!(report.largest_shift_texels <= export::geometry::MAX_SHIFT);

    let want = draw(&p.scene, set);
    for pages in [Pages::Linear, Pages::Png] {
        let back = read(&out, pages).unwrap();
        assert_eq!(
            back.polygons.len(),
            p.scene.polygons.len(),
            "{name}: every polygon"
        );
        for (a, b) in back.polygons.iter().zip(&p.scene.polygons) {
            for k in 0..4 {
                let d = (a.corners[k] - b.corners[k]).length();
                assert!(
                    d <= 1e-6 * (1.0 + b.corners[k].length()),
                    "{name}: corner moved by {d}"
                );
            }
        }
        for (k, bounds) in back.uv_bounds.iter().enumerate() {
            let c = &back.charts[k];
            let (w, h, _) = &back.pages[c.page as usize];
            let g = back.gutter as f32;
            let lo = [(c.x as f32 + g) / *w as f32, (c.y as f32 + g) / *h as f32];
            let (cw, ch) = (c.width as f32, c.height as f32);
            let hi = [lo[0] + cw / *w as f32, lo[1] + ch / *h as f32];
            let eps = 1e-6;
            assert!(
                bounds[0] >= lo[0] - eps
                    && bounds[1] >= lo[1] - eps
                    && bounds[2] <= hi[0] + eps
                    && bounds[3] <= hi[1] + eps,
                "{name}: polygon {k}'s coordinates {bounds:?} leave its chart {lo:?}..{hi:?}"
            );
        }
        let scene = Scene::new(
            p.scene.camera,
            p.scene.width,
            p.scene.height,
            p.scene.materials.clone(),
            back.polygons.clone(),
        );
        let got = draw(&scene, &back.textures().unwrap());
        match pages {
            Pages::Linear => {
                // The same texels (f32 in the EXR), gutters rebuilt to an ulp, f32 corners:
                // equal to a few ulps of the radiosity. A triangle's chart is affine; this
                // reader resamples it back to the (u, v) square the texture method reads, which
                // is exact to second order but not at a triangle's apex, where the square's u
                // degenerates: there a few pixels may differ more (at most 0.1 % of them, and
                // every pixel within 1 % of the scale).
                let scale = want.iter().fold(1e-3f32, |m, v| m.max(v.max_element()));
                let diffs: Vec<f32> = want
                    .iter()
                    .zip(&got)
                    .map(|(a, b)| (*a - *b).abs().max_element())
                    .collect();
                let worst = diffs.iter().fold(0.0f32, |m, d| m.max(*d));
                let over = diffs.iter().filter(|d| **d > 1e-4 * scale).count();
                eprintln!(
                    "{name}.{container}: linear pages, largest difference {worst:.3e} (largest \
                     value {scale:.3e}), {over} pixels over 1e-4 of it"
                );
                assert!(
                    worst <= 1e-2 * scale && over as f64 <= 0.001 * want.len() as f64,
                    "{name}: linear pages differ by {worst} (scale {scale}) on {over} pixels"
                );
                let squares_only = p
                    .scene
                    .polygons
                    .iter()
                    .all(|q| q.shape == scene::Shape::Quad);
                assert!(!squares_only || over == 0, "{name}: {over} pixels differ");
            }
            Pages::Png => {
                let e = exposure as f32;
                let off = want
                    .iter()
                    .zip(&got)
                    .filter(|(a, b)| {
                        (0..3).any(|c| {
                            (to_srgb8(a[c], e) as i32 - to_srgb8(b[c], e) as i32).abs() > 1
                        })
                    })
                    .count();
                let exact = want
                    .iter()
                    .zip(&got)
                    .filter(|(a, b)| (0..3).all(|c| to_srgb8(a[c], e) == to_srgb8(b[c], e)))
                    .count();
                eprintln!("{name}.{container}: PNG pages, {exact} of {} pixels equal in 8 bits, {off} more than one level off", want.len());
                assert!(
                    off as f64 <= 0.001 * want.len() as f64,
                    "{name}: {off} of {} pixels differ by more than 1/255",
                    want.len()
                );
            }
        }
    }
}

fn tempdir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("pixelflow-export-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn cornell_box_lightmap_round_trips_through_glb_and_gltf() {
    let p = crate::shipped("cornell-box");
    round_trip("cornell-box", p, "glb");
    round_trip("cornell-box-json", p, "gltf");
}

#[test]
fn gallery_lightmap_round_trips() {
    round_trip("gallery", crate::shipped("gallery"), "glb");
}

/// The mesh export holds every triangle of the mesh method with its Gouraud colours.
#[test]
fn mesh_export_holds_every_triangle() {
    let p = crate::shipped("cornell-box");
    let (mesh, _) = p.mesh().unwrap();
    let out = tempdir("mesh").join("mesh.glb");
    let r = export_mesh(&p.scene, mesh, 0.0, &out, &base::output::Outputs::new()).unwrap();
    assert_eq!(r.triangles, mesh.scene.polygons.len());
    let g = gltf::Gltf::open(&out).unwrap();
    let blob = g.blob.clone().unwrap();
    let mut triangles = 0;
    for prim in g.meshes().flat_map(|m| m.primitives().collect::<Vec<_>>()) {
        let reader = prim.reader(|_| Some(&blob[..]));
        triangles += reader.read_indices().unwrap().into_u32().count() / 3;
        let colours: Vec<[f32; 3]> = reader.read_colors(0).unwrap().into_rgb_f32().collect();
        assert!(colours.iter().flatten().all(|c| (0.0..=1.0).contains(c)));
    }
    assert_eq!(triangles, mesh.scene.polygons.len());
    // Vertices are shared within a polygon where the light agrees: far fewer than three per
    // triangle (an adaptive mesh's inner vertex has about six triangles round it).
    assert!(
        (r.vertices as f64) < 0.5 * 3.0 * r.triangles as f64,
        "{} vertices for {} triangles",
        r.vertices,
        r.triangles
    );
}

/// An export keeps the model: a node and a mesh per scene object, named after it, the scene's
/// materials by name, and the scene's camera as a camera node looking where it looks.
#[test]
fn exports_keep_objects_materials_and_the_camera() {
    let p = crate::shipped("cornell-box");
    let (set, _) = p.textures().unwrap();
    let (mesh, _) = p.mesh().unwrap();
    let dir = tempdir("model");
    let outputs = base::output::Outputs::new();
    export_lightmap(
        &p.scene,
        set,
        p.expanded().unwrap().0,
        4096,
        0.0,
        &dir.join("l.glb"),
        &outputs,
    )
    .unwrap();
    export_mesh(&p.scene, mesh, 0.0, &dir.join("m.glb"), &outputs).unwrap();
    for file in ["l.glb", "m.glb"] {
        let g = gltf::Gltf::open(dir.join(file)).unwrap();
        let names: Vec<String> = g
            .nodes()
            .filter(|n| n.mesh().is_some())
            .map(|n| n.name().unwrap().to_string())
            .collect();
        let mut objects: Vec<String> = p.scene.objects.clone();
        objects.retain(|o| {
            p.scene
                .polygons
                .iter()
                .any(|q| p.scene.objects[q.object as usize] == *o)
        });
        assert_eq!(names, objects, "{file}");
        for m in g.materials() {
            let name = m.name().unwrap();
            assert!(
                p.scene.materials.iter().any(|s| name.starts_with(&s.name)),
                "{file}: {name}"
            );
        }
        let cam = g
            .nodes()
            .find(|n| n.camera().is_some())
            .expect("a camera node");
        let (t, r, _) = cam.transform().decomposed();
        let eye = p.scene.camera.eye;
        assert!((glam::DVec3::from_array(t.map(f64::from)) - eye).length() < 1e-5);
        // The node's -Z, turned by its rotation, points from the eye to look_at.
        let dir = glam::Quat::from_array(r)
            .mul_vec3(-glam::Vec3::Z)
            .as_dvec3();
        let want = (p.scene.camera.look_at - eye).normalize();
        assert!((dir - want).length() < 1e-5, "{file}: {dir} against {want}");
        match cam.camera().unwrap().projection() {
            gltf::camera::Projection::Perspective(q) => {
                assert!(
                    (q.yfov().to_degrees() - 39.3076).abs() < 1e-3,
                    "{}",
                    q.yfov()
                );
            }
            _ => panic!("{file}: the Cornell box's camera is perspective"),
        }
    }
}

/// An engine samples the page, not the polygon's texture: at a polygon's edge its bilinear
/// lookup in the linear page returns the RRP's own value on the edge (what the gutter is for),
/// so polygons whose RRPs meet along an edge meet in the atlas too, and its Mitchell-Netravali
/// lookup returns what the project's bicubic texture method reads there (no neighbouring chart
/// reaches into the 4 x 4 footprint). Three texel centres along each of the four edges of every
/// polygon of the Cornell box; the bound is f32 rounding of the gutter's reflections (relative
/// 1e-5 of the largest value of the polygon's chart). Triangles' affine charts are held to the
/// bilinear bound on their three edges (see the end of the test).
#[test]
fn atlas_lookups_at_polygon_edges_return_the_rrp_edge_values() {
    let p = crate::shipped("cornell-box");
    let (set, _) = p.textures().unwrap();
    let out = tempdir("edges").join("edges.glb");
    export_lightmap(
        &p.scene,
        set,
        p.expanded().unwrap().0,
        4096,
        0.0,
        &out,
        &base::output::Outputs::new(),
    )
    .unwrap();
    let back = read(&out, Pages::Linear).unwrap();
    let (recon, _) = p.expanded().unwrap();
    let mitchell = reconstruction::texture::Cubic::new(1.0 / 3.0, 1.0 / 3.0);
    let mut checked = 0;
    let mut worst_triangle = [[0.0f32; 2]; 3];
    for (k, c) in back.charts.iter().enumerate() {
        let (w, h, texels) = &back.pages[c.page as usize];
        let at = |x: i64, y: i64| {
            texels[(y.clamp(0, *h as i64 - 1) * *w as i64 + x.clamp(0, *w as i64 - 1)) as usize]
        };
        // The page coordinate (in texels, centres at + 0.5) of parameter (u, v).
        let g = back.gutter as f64;
        let xy = |u: f64, v: f64| {
            let (u, v) = if c.triangle {
                export::atlas::affine_of_square(u, v)
            } else {
                (u, v)
            };
            (
                c.x as f64 + g + u * c.width as f64 - 0.5,
                c.y as f64 + g + v * c.height as f64 - 0.5,
            )
        };
        let bilinear = |u: f64, v: f64| {
            let (x, y) = xy(u, v);
            let (i, j) = (x.floor(), y.floor());
            let (fx, fy) = ((x - i) as f32, (y - j) as f32);
            let (i, j) = (i as i64, j as i64);
            let top = at(i, j) * (1.0 - fx) + at(i + 1, j) * fx;
            let bottom = at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx;
            top * (1.0 - fy) + bottom * fy
        };
        let bicubic = |u: f64, v: f64| {
            let (x, y) = xy(u, v);
            let (i, j) = (x.floor(), y.floor());
            let (wx, wy) = (
                mitchell.weights((x - i) as f32),
                mitchell.weights((y - j) as f32),
            );
            let mut sum = glam::Vec3::ZERO;
            for (b, wyb) in wy.iter().enumerate() {
                for (a, wxa) in wx.iter().enumerate() {
                    sum += at(i as i64 - 1 + a as i64, j as i64 - 1 + b as i64) * (wxa * wyb);
                }
            }
            sum
        };
        let (ew, eh) = (
            c.width as i64 + 2 * back.gutter as i64,
            c.height as i64 + 2 * back.gutter as i64,
        );
        let largest = (0..ew * eh)
            .map(|q| {
                at(c.x as i64 + q % ew, c.y as i64 + q / ew)
                    .abs()
                    .max_element()
            })
            .fold(1e-6f32, f32::max);
        let tex = &set.textures[k];
        for j in 0..3 {
            // Along each edge at the first, middle and last texel centres, where bilinear
            // filtering along it is exact (a triangle's chart is square: the two agree).
            let index = |n: u32| [0, n / 2, n - 1][j];
            let centre = |n: u32| (index(n) as f64 + 0.5) / n as f64;
            let (tu, tv) = (centre(c.width), centre(c.height));
            let last = index(c.width) == c.width - 1;
            for (edge, (u, v)) in [(0.0, tv), (1.0, tv), (tu, 0.0), (tu, 1.0)]
                .into_iter()
                .enumerate()
            {
                let rrp = recon.eval(k as u32, u as f32, v as f32);
                let own = tex.sample(0, u as f32, v as f32, Filter::MITCHELL);
                for (name, got, want) in [
                    ("bilinear", bilinear(u, v), rrp),
                    ("bicubic", bicubic(u, v), own),
                ] {
                    let d = (got - want).abs().max_element();
                    if c.triangle {
                        if edge < 3 && !last {
                            let w = &mut worst_triangle[edge][usize::from(name == "bicubic")];
                            *w = w.max(d / largest);
                        }
                    } else {
                        assert!(
                            d <= 1e-5 * largest,
                            "polygon {k} at ({u}, {v}), {name}: {got} vs {want}"
                        );
                    }
                    checked += 1;
                }
            }
        }
    }
    assert_eq!(checked, 24 * p.scene.polygons.len());
    eprintln!(
        "triangle charts: worst edge lookups [edge][bilinear, bicubic] {worst_triangle:?} of \
         the chart's largest value"
    );
    // A triangle's affine chart: bilinear lookups on its three edges return the RRP's edge
    // values as exactly as a square chart's (the odd reflection through the edge); its bicubic
    // lookups differ from the square texture's own by the two layouts' different footprints.
    // The apex (the square's edge v = 1, one point, where the RRP's u is meaningless) and the
    // texel beside it are left out.
    for (edge, [bilinear, bicubic]) in worst_triangle.iter().enumerate() {
        assert!(*bilinear <= 1e-5, "edge {edge}: bilinear {bilinear}");
        assert!(*bicubic <= 2e-3, "edge {edge}: bicubic {bicubic}");
    }
}

/// An export loads back as the scene it was made of: `render model.glb` rebuilds each polygon
/// from its vertices' `_POLYGON` and `TEXCOORD_0` (the corners at (u, v) = (0, 0) ... (0, 1)),
/// takes the scene materials' reflectance and emission from their `extras`, and looks through
/// the exported camera, so it solves and renders what the source scene does (the same image
/// within 1/255 on every pixel, measured with `render`; here the scene itself is compared).
#[test]
fn an_export_loads_back_as_the_scene_it_was_made_of() {
    let p = crate::shipped("cornell-box");
    let (set, _) = p.textures().unwrap();
    let (mesh, _) = p.mesh().unwrap();
    let dir = tempdir("back");
    let outputs = base::output::Outputs::new();
    export_lightmap(
        &p.scene,
        set,
        p.expanded().unwrap().0,
        4096,
        0.0,
        &dir.join("l.glb"),
        &outputs,
    )
    .unwrap();
    export_mesh(&p.scene, mesh, 0.0, &dir.join("m.glb"), &outputs).unwrap();
    let back = scene::load_scene(&dir.join("l.glb")).unwrap();
    assert_eq!(back.polygons.len(), p.scene.polygons.len());
    // Within f32 rounding of the positions, in the order of the objects and materials.
    let mut ours: Vec<&scene::Polygon> = p.scene.polygons.iter().collect();
    let mut theirs: Vec<&scene::Polygon> = back.polygons.iter().collect();
    let key = |q: &&scene::Polygon| {
        let c = q.corners.iter().fold(glam::DVec3::ZERO, |s, c| s + *c) / 4.0;
        (c * 1e4).round().to_array().map(|x| x as i64)
    };
    ours.sort_by_key(key);
    theirs.sort_by_key(key);
    for (a, b) in ours.iter().zip(&theirs) {
        assert_eq!(a.shape, b.shape);
        for (x, y) in a.corners.iter().zip(&b.corners) {
            assert!((*x - *y).length() < 1e-5, "{x} against {y}");
        }
        let (ma, mb) = (
            &p.scene.materials[a.material as usize],
            &back.materials[b.material as usize],
        );
        assert_eq!(ma.reflectance, mb.reflectance);
        assert_eq!(ma.emission, mb.emission);
    }
    assert!((back.camera.eye - p.scene.camera.eye).length() < 1e-5);
    assert!(
        (back.camera.look_at - back.camera.eye)
            .normalize()
            .dot((p.scene.camera.look_at - p.scene.camera.eye).normalize())
            > 1.0 - 1e-9
    );
    // The mesh export is triangles of the adaptive mesh, not polygons: it loads as them.
    let m = scene::load_scene(&dir.join("m.glb")).unwrap();
    assert!(m.polygons.len() > p.scene.polygons.len());
}

/// What broke: the piece of a wall under a lamp mounted flush (1e-9 in front of it, facing the
/// room, or in its very plane) was exported with it; their depths tie in any engine's depth buffer, so a viewer drew
/// the lamp flickering with the piece's black. Both exports now leave the buried pieces out
/// (the lightmap's `_POLYGON` ids skip them) and keep every other polygon.
#[test]
fn exports_leave_out_the_pieces_buried_under_flush_faces() {
    let path = std::path::Path::new(crate::REPO).join("scenes/hard/flush.toml");
    let p = app::prepare::prepare_path(
        &app::context::Context::default(),
        &path,
        &app::context::TextureOptions::default(),
    )
    .unwrap();
    let open: Vec<u32> = (0..p.scene.polygons.len() as u32)
        .filter(|&i| p.scene.polygons[i as usize].sealed != scene::seal::Sealed::Buried)
        .collect();
    assert_eq!(open.len() + 4, p.scene.polygons.len(), "four pieces buried");
    let (set, _) = p.textures().unwrap();
    let (mesh, _) = p.mesh().unwrap();
    let dir = tempdir("flush");
    let outputs = base::output::Outputs::new();
    let out = dir.join("l.glb");
    let l = export_lightmap(
        &p.scene,
        set,
        p.expanded().unwrap().0,
        4096,
        0.0,
        &out,
        &outputs,
    );
    assert_eq!(l.unwrap().polygons, open.len());
    let back = read(&out, Pages::Linear).unwrap();
    assert_eq!(back.ids, open);
    for (a, &i) in back.polygons.iter().zip(&back.ids) {
        let b = &p.scene.polygons[i as usize];
        let d = (0..4).map(|k| (a.corners[k] - b.corners[k]).length());
        assert!(d.fold(0.0, f64::max) < 1e-6, "polygon {i}");
    }
    let m = export_mesh(&p.scene, mesh, 0.0, &dir.join("m.glb"), &outputs).unwrap();
    let kept = mesh
        .source_polygon
        .iter()
        .filter(|s| open.contains(s))
        .count();
    assert!(kept < mesh.scene.polygons.len());
    assert_eq!((m.polygons, m.triangles), (open.len(), kept));
}
