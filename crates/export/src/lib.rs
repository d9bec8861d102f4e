//! Export: a radiosity solution out of the tool, as glTF 2.0 that engines, Blender and three.js
//! load.
//!
//! Two forms:
//! - **Lightmap** ([`export_lightmap`]): the original polygons, each with its radiosity texture
//!   (the texels the texture methods draw, resampled from its RRP) packed into a lightmap atlas
//!   ([`atlas`]). Texture coordinate set 1 addresses the atlas, set 0 holds the polygon's own
//!   (u, v) parameters. The pages are written twice: sRGB PNG after the scene's exposure
//!   (clamped to [0, 1], the same encoding as `render`'s PNG), referenced by the materials; and
//!   linear float OpenEXR beside the file (radiosity in W/m^2, no exposure), named in the
//!   asset's `extras`.
//! - **Mesh** ([`export_mesh`]): the adaptive mesh the mesh method draws, with the Gouraud
//!   vertex colours as `COLOR_0` (linear, after exposure, clamped to [0, 1]) and the unclamped
//!   radiosity as the attribute `_RADIOSITY`.
//!
//! Both keep the model's structure: a node and a mesh per scene object, named after it, and the
//! scene's camera as a camera node. Both leave out the buried polygons (`scene::seal`: the wall
//! under a poster or a lamp mounted flush, a hair behind it): their depths tie with their
//! covers' in any engine's depth buffer, so they would flicker through, and the faces over them
//! hide them from every eye in front. Both bake the lighting, so every material is
//! `KHR_materials_unlit`; each keeps the scene
//! material's diffuse reflectance and emission in its `extras` for engines that relight. Every
//! vertex carries `_POLYGON`, the scene polygon it belongs to. The container follows the file
//! name: `.glb` embeds the buffer and the PNG pages, `.gltf` writes them beside it. All files
//! of one export are written as one batch (temporaries renamed together).
//!
//! Invariants: the output is a pure function of the scene, the solution and the options (the
//! packer is deterministic, groups are ordered); every number written is finite.

#![forbid(unsafe_code)]

pub mod atlas;
pub mod document;
pub mod geometry;
pub mod readback;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Serialize;

use atlas::{Atlas, AtlasStats};
use base::error::{Error, Result};
use base::output::Outputs;
use document::{Builder, Vertices};
use gltf::json;
use imageio::write::{encode_exr, encode_png};
use imageio::ImageView;
use reconstruction::mesh::MeshModel;
use reconstruction::texture::TextureSet;
use scene::Scene;

/// The glTF container, chosen by the output's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Container {
    /// Binary glTF: one file.
    Glb,
    /// JSON glTF with its buffer and images beside it.
    Gltf,
}

impl Container {
    /// The container `path`'s extension names (`.glb` or `.gltf`, any case).
    pub fn of(path: &Path) -> Result<Container> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
        {
            Some(e) if e == "glb" => Ok(Container::Glb),
            Some(e) if e == "gltf" => Ok(Container::Gltf),
            _ => Err(Error::invalid_option(
                "output",
                path.display().to_string(),
                "must end in .glb (one binary file) or .gltf (JSON with its files beside it)",
            )),
        }
    }
}

/// What an export wrote and measured.
#[derive(Debug, Clone, Serialize)]
pub struct ExportReport {
    /// `lightmap` or `mesh`.
    pub kind: &'static str,
    /// Every file written, the glTF first.
    pub files: Vec<PathBuf>,
    /// Scene polygons exported.
    pub polygons: usize,
    /// Triangles written.
    pub triangles: usize,
    /// Vertices written.
    pub vertices: usize,
    /// The atlas's packing and texel density (lightmaps).
    pub atlas: Option<AtlasStats>,
    /// Largest distance, in texel widths, between where an engine's interpolation and the
    /// polygon's parameters put a texel (lightmaps; see [`geometry`]).
    pub largest_shift_texels: f64,
    /// The exposure (stops) the PNG pages and `COLOR_0` were encoded with.
    pub exposure: f64,
}

/// A sibling of `out`: its stem followed by `suffix`.
pub fn sibling(out: &Path, suffix: &str) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    out.with_file_name(format!("{stem}{suffix}"))
}

/// A file name as the glTF refers to it (beside the glTF itself).
fn uri_of(path: &Path) -> String {
    path.file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Material `extras`: what engines that relight need.
fn material_extras(scene: &Scene, m: u32) -> serde_json::Value {
    let mat = &scene.materials[m as usize];
    serde_json::json!({ "pixelflow": {
        "material": m,
        "reflectance": mat.reflectance.to_array(),
        "emission": mat.emission.to_array(),
    }})
}

/// Writes the lightmap export of `scene` (textures `set`, centre-placed, one per polygon, and
/// the reconstruction `recon` they sample, which fills the triangles' affine charts) to `out`
/// (`.glb` or `.gltf`), its pages at most `page_size` texels a side, PNG pages after
/// `exposure` stops.
pub fn export_lightmap(
    scene: &Scene,
    set: &TextureSet,
    recon: &reconstruction::Reconstruction,
    page_size: u32,
    exposure: f64,
    out: &Path,
    outputs: &Outputs,
) -> Result<ExportReport> {
    let container = Container::of(out)?;
    check_polygons(scene)?;
    let atlas = Atlas::build(scene, set, recon, page_size)?;
    let mut batch = outputs.batch();
    let mut files = vec![out.to_path_buf()];
    let mut linear = Vec::new();
    let mut pngs = Vec::new();
    for (k, page) in atlas.pages.iter().enumerate() {
        let view = ImageView {
            width: page.width,
            height: page.height,
            pixels: &page.texels,
        };
        let exr = sibling(out, &format!(".lightmap-{k}.exr"));
        batch.stage(&exr, &encode_exr(view)?)?;
        linear.push(uri_of(&exr));
        files.push(exr);
        pngs.push(encode_png(view, exposure)?);
    }
    let extras = serde_json::json!({ "pixelflow": {
        "kind": "lightmap",
        "exposure": exposure,
        "gutter": atlas.gutter,
        "linear_pages": linear,
        "units": "linear_pages: radiosity in W/m^2 per channel; PNG pages: sRGB after 2^exposure, clamped to [0, 1]",
    }});
    let mut b = Builder::new(extras)?;
    let mut textures = Vec::new();
    for (k, png) in pngs.iter().enumerate() {
        let uri = match container {
            Container::Glb => None,
            Container::Gltf => {
                let path = sibling(out, &format!(".lightmap-{k}.png"));
                batch.stage(&path, png)?;
                let u = uri_of(&path);
                files.push(path);
                Some(u)
            }
        };
        textures.push(b.png_texture(&format!("lightmap {k}"), png, uri));
    }
    let (groups, shift) = lightmap_groups(scene, &atlas);
    let mut materials = BTreeMap::new();
    let mut meshes = ObjectMeshes::new();
    let (mut triangles, mut vertices) = (0, 0);
    for ((object, m, page), v) in &groups {
        let mat = match materials.get(&(*m, *page)) {
            Some(&mat) => mat,
            None => {
                let name = format!("{} (lightmap {page})", scene.materials[*m as usize].name);
                let texture = Some((textures[*page as usize], 1));
                let mat = b.unlit_material(&name, texture, material_extras(scene, *m))?;
                *materials.entry((*m, *page)).or_insert(mat)
            }
        };
        let primitive = b.primitive(v, mat);
        meshes.entry(*object).or_default().push(primitive);
        triangles += v.indices.len() / 3;
        vertices += v.position.len();
    }
    finish(b, scene, meshes, (container, out), &mut batch, &mut files)?;
    batch.commit()?;
    Ok(ExportReport {
        kind: "lightmap",
        files,
        polygons: scene.polygons.iter().filter(|p| exported(p)).count(),
        triangles,
        vertices,
        atlas: Some(atlas.stats(scene)),
        largest_shift_texels: shift,
        exposure,
    })
}

/// Whether polygon `p` goes into an export: all but the buried ones.
fn exported(p: &scene::Polygon) -> bool {
    p.sealed != scene::seal::Sealed::Buried
}

fn check_polygons(scene: &Scene) -> Result<()> {
    if scene.polygons.len() > document::MAX_POLYGONS {
        return Err(Error::limit(
            "polygons in a glTF export",
            scene.polygons.len() as u64,
            document::MAX_POLYGONS as u64,
        ));
    }
    Ok(())
}

/// The lightmap's vertices grouped by (object, material, page), in polygon order within each
/// group, and the largest texel shift of the tessellations.
fn lightmap_groups(scene: &Scene, atlas: &Atlas) -> (BTreeMap<(u32, u32, u32), Vertices>, f64) {
    let mut groups: BTreeMap<(u32, u32, u32), Vertices> = BTreeMap::new();
    let mut shift: f64 = 0.0;
    for (p, poly) in scene.polygons.iter().enumerate() {
        if !exported(poly) {
            continue;
        }
        let chart = &atlas.charts[p];
        let t = geometry::tessellate(poly, (chart.width, chart.height));
        shift = shift.max(t.shift);
        let v = groups
            .entry((poly.object, poly.material, chart.page))
            .or_insert_with(|| Vertices {
                tex_coords: vec![Vec::new(), Vec::new()],
                custom: vec![("POLYGON".into(), json::accessor::Type::Scalar, Vec::new())],
                ..Default::default()
            });
        let base = v.position.len() as u32;
        for &[u, w] in &t.uv {
            let x = poly.point(u, w);
            v.position.push(x.as_vec3().to_array());
            // A smooth surface's vertex normals go out as they came in.
            v.normal.push(poly.shading_normal(x).as_vec3().to_array());
            v.tex_coords[0].push([u as f32, w as f32]);
            v.tex_coords[1].push(atlas.uv(p, u, w));
            v.custom[0].2.push(p as f32);
        }
        for tri in &t.triangles {
            v.indices.extend(tri.iter().map(|i| base + i));
        }
    }
    (groups, shift)
}

/// Per object with primitives, in object order: its name (the scene's, unique: a repeated name
/// gets `#2`, `#3`, ...) and its primitives.
fn named_meshes(scene: &Scene, meshes: ObjectMeshes) -> Vec<(String, Vec<json::mesh::Primitive>)> {
    let mut seen: BTreeMap<String, u32> = BTreeMap::new();
    meshes
        .into_iter()
        .map(|(o, primitives)| {
            let base = scene
                .objects
                .get(o as usize)
                .cloned()
                .unwrap_or_else(|| format!("object {o}"));
            let n = seen.entry(base.clone()).or_insert(0);
            *n += 1;
            let name = if *n == 1 { base } else { format!("{base}#{n}") };
            (name, primitives)
        })
        .collect()
}

/// The scene's camera as a glTF camera node: a perspective camera keeps the vertical field of
/// view and the image's aspect ratio, an orthographic one half its width and height (`xmag`,
/// `ymag`); the node sits at the eye, turned so its -Z looks at `look_at` with +Y towards `up`.
fn camera_node(scene: &Scene) -> Option<document::CameraNode> {
    use scene::Projection;
    let c = &scene.camera;
    let forward = (c.look_at - c.eye).normalize_or_zero();
    let right = forward.cross(c.up).normalize_or_zero();
    if forward == glam::DVec3::ZERO || right == glam::DVec3::ZERO {
        return None;
    }
    let up = right.cross(forward);
    let rotation = glam::DQuat::from_mat3(&glam::DMat3::from_cols(right, up, -forward));
    let aspect = scene.width as f64 / scene.height.max(1) as f64;
    let (type_, perspective, orthographic) = match c.projection {
        Projection::Perspective { fov_y_deg } => (
            json::camera::Type::Perspective,
            Some(json::camera::Perspective {
                aspect_ratio: Some(aspect as f32),
                yfov: fov_y_deg.to_radians() as f32,
                zfar: None,
                znear: 0.01,
                extensions: None,
                extras: Default::default(),
            }),
            None,
        ),
        Projection::Orthographic { width, height } => (
            json::camera::Type::Orthographic,
            None,
            Some(json::camera::Orthographic {
                xmag: (width / 2.0) as f32,
                ymag: (height / 2.0) as f32,
                zfar: 1e6,
                znear: 0.0,
                extensions: None,
                extras: Default::default(),
            }),
        ),
    };
    Some(document::CameraNode {
        camera: json::Camera {
            name: Some("camera".into()),
            orthographic,
            perspective,
            type_: json::validation::Checked::Valid(type_),
            extensions: None,
            extras: Default::default(),
        },
        translation: c.eye.as_vec3().to_array(),
        rotation: rotation.normalize().as_quat().to_array(),
    })
}

/// The primitives of each scene object, by object index.
type ObjectMeshes = BTreeMap<u32, Vec<json::mesh::Primitive>>;

/// Finishes the document (a node per object of `meshes`, named as [`named_meshes`] says, and
/// the scene's camera node) and stages it (and, for `.gltf`, its buffer) in `batch`.
fn finish(
    b: Builder,
    scene: &Scene,
    meshes: ObjectMeshes,
    (container, out): (Container, &Path),
    batch: &mut base::output::Batch,
    files: &mut Vec<PathBuf>,
) -> Result<()> {
    let (meshes, camera) = (named_meshes(scene, meshes), camera_node(scene));
    match container {
        Container::Glb => {
            let (root, bin) = b.finish(meshes, camera, None);
            batch.stage(out, &document::glb(&root, bin)?)
        }
        Container::Gltf => {
            let bin_path = sibling(out, ".bin");
            let (root, bin) = b.finish(meshes, camera, Some(uri_of(&bin_path)));
            batch.stage(&bin_path, &bin)?;
            files.push(bin_path);
            batch.stage(out, &document::gltf_text(&root)?)
        }
    }
}

/// A vertex of the mesh export, by its bits: the polygon, the position and the radiosity. Two
/// triangles of one polygon that meet at a point with the same light share the vertex there.
type VertexKey = (u32, [u32; 3], [u32; 3]);

/// The mesh's triangles grouped by (object, material), each group's vertices shared where
/// their polygon, position and radiosity agree (with the index of each); `COLOR_0` is the
/// radiosity times `scale`, clamped to [0, 1].
fn mesh_groups(
    scene: &Scene,
    mesh: &MeshModel,
    scale: f32,
) -> BTreeMap<(u32, u32), (Vertices, std::collections::HashMap<VertexKey, u32>)> {
    let mut groups: BTreeMap<(u32, u32), (Vertices, std::collections::HashMap<VertexKey, u32>)> =
        BTreeMap::new();
    for (k, tri) in mesh.scene.polygons.iter().enumerate() {
        if !exported(tri) {
            continue;
        }
        let source = mesh.source_polygon[k];
        let object = scene.polygons.get(source as usize).map_or(0, |p| p.object);
        let (v, index) = groups.entry((object, tri.material)).or_insert_with(|| {
            let v = Vertices {
                custom: vec![
                    ("RADIOSITY".into(), json::accessor::Type::Vec3, Vec::new()),
                    ("POLYGON".into(), json::accessor::Type::Scalar, Vec::new()),
                ],
                ..Default::default()
            };
            (v, Default::default())
        });
        let patch = &mesh.patch(k);
        let n = tri.normal.normalize_or_zero().as_vec3().to_array();
        for (corner, (s, t)) in [(0, (0.0, 0.0)), (1, (1.0, 0.0)), (2, (0.0, 1.0))] {
            let c: Vec3 = patch.eval(s, t);
            let p = tri.corners[corner].as_vec3().to_array();
            let key = (source, p.map(f32::to_bits), c.to_array().map(f32::to_bits));
            let next = v.position.len() as u32;
            let i = *index.entry(key).or_insert(next);
            if i == next {
                v.position.push(p);
                v.normal.push(n);
                v.colour
                    .push((c * scale).clamp(Vec3::ZERO, Vec3::ONE).to_array());
                v.custom[0].2.extend(c.to_array());
                v.custom[1].2.push(source as f32);
            }
            v.indices.push(i);
        }
    }
    groups
}

/// Writes the adaptive mesh of a solution (`mesh`, built from `scene`) with Gouraud vertex
/// colours to `out` (`.glb` or `.gltf`), `COLOR_0` after `exposure` stops.
pub fn export_mesh(
    scene: &Scene,
    mesh: &MeshModel,
    exposure: f64,
    out: &Path,
    outputs: &Outputs,
) -> Result<ExportReport> {
    let container = Container::of(out)?;
    check_polygons(scene)?;
    let extras = serde_json::json!({ "pixelflow": {
        "kind": "mesh",
        "exposure": exposure,
        "units": "_RADIOSITY: radiosity in W/m^2 per channel; COLOR_0: linear after 2^exposure, clamped to [0, 1]",
    }});
    let mut b = Builder::new(extras)?;
    let groups = mesh_groups(scene, mesh, exposure.exp2() as f32);
    let mut materials = BTreeMap::new();
    let mut meshes = ObjectMeshes::new();
    let (mut triangles, mut vertices) = (0, 0);
    for ((object, m), (v, _)) in &groups {
        let mat = match materials.get(m) {
            Some(&mat) => mat,
            None => {
                let name = scene.materials[*m as usize].name.clone();
                let mat = b.unlit_material(&name, None, material_extras(scene, *m))?;
                *materials.entry(*m).or_insert(mat)
            }
        };
        let primitive = b.primitive(v, mat);
        meshes.entry(*object).or_default().push(primitive);
        triangles += v.indices.len() / 3;
        vertices += v.position.len();
    }
    let mut batch = outputs.batch();
    let mut files = vec![out.to_path_buf()];
    finish(b, scene, meshes, (container, out), &mut batch, &mut files)?;
    batch.commit()?;
    Ok(ExportReport {
        kind: "mesh",
        files,
        polygons: scene.polygons.iter().filter(|p| exported(p)).count(),
        triangles,
        vertices,
        atlas: None,
        largest_shift_texels: 0.0,
        exposure,
    })
}
