//! Tests of glTF input: small files built here by a tiny writer (JSON with a base64 `data:`
//! buffer, a GLB with a binary chunk, a `.gltf` with a `.bin` beside it), loaded through the
//! scene loader with the files held in memory, and checked value by value.

use super::lights::cone_falloff;
use crate::checks::LoadOptions;
use crate::checks::Readers;
use crate::parse::parse_scene_options;
use crate::{parse_scene_with_bytes, Scene};
use base::error::{Error, EXIT_BAD_INPUT};
use glam::DVec3;
use proptest::prelude::*;
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A glTF document being written: one buffer, its views and accessors.
#[derive(Default, Clone)]
struct Doc {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Doc {
    /// Appends `bytes` to the buffer (4-byte aligned) as a new buffer view; its index.
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()
        }));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    /// A VEC3 FLOAT accessor of `points`, with their bounds (glTF requires them of positions);
    /// its index.
    fn positions(&mut self, points: &[[f32; 3]]) -> usize {
        let bytes: Vec<u8> = points
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let view = self.view(&bytes);
        let bound = |f: fn(f32, f32) -> f32| {
            (0..3)
                .map(|k| points.iter().map(|p| p[k]).reduce(f).unwrap_or(0.0))
                .collect::<Vec<f32>>()
        };
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5126, "count": points.len(), "type": "VEC3",
            "min": bound(f32::min), "max": bound(f32::max)
        }));
        self.accessors.len() - 1
    }

    /// An UNSIGNED_SHORT SCALAR accessor of `indices`; its index.
    fn indices(&mut self, indices: &[u16]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5123, "count": indices.len(), "type": "SCALAR"
        }));
        self.accessors.len() - 1
    }

    /// `doc` with the asset, the buffer (at `uri`, or the GLB chunk for `None`), the views and
    /// the accessors filled in.
    fn json(&self, mut doc: Value, uri: Option<String>) -> Value {
        let mut buffer = json!({ "byteLength": self.bin.len() });
        if let Some(u) = uri {
            buffer["uri"] = json!(u);
        }
        doc["asset"] = json!({ "version": "2.0", "generator": "pixelflow-sim tests" });
        doc["buffers"] = json!([buffer]);
        doc["bufferViews"] = json!(self.views);
        doc["accessors"] = json!(self.accessors);
        doc
    }

    /// A `.gltf` whose buffer is a base64 data URI.
    fn gltf(&self, doc: Value) -> Vec<u8> {
        let uri = format!("data:application/octet-stream;base64,{}", base64(&self.bin));
        serde_json::to_vec_pretty(&self.json(doc, Some(uri))).unwrap()
    }

    /// A `.gltf` whose buffer is the file `name` beside it, and that file's bytes.
    fn gltf_and_bin(&self, doc: Value, uri: &str) -> (Vec<u8>, Vec<u8>) {
        let text = serde_json::to_vec(&self.json(doc, Some(uri.to_string()))).unwrap();
        (text, self.bin.clone())
    }

    /// A `.glb`: the JSON chunk (padded with spaces) and the binary chunk (padded with zeros).
    fn glb(&self, doc: Value) -> Vec<u8> {
        let mut json = serde_json::to_vec(&self.json(doc, None)).unwrap();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }
}

/// Standard base64 with padding (the writer's side of `data::decode_base64`).
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                out.push(char::from(A[(n >> (18 - 6 * k) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// The unit quad in z = 0 (front +z) as two triangles: positions and indices.
fn quad(doc: &mut Doc) -> Value {
    let p = doc.positions(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ]);
    let i = doc.indices(&[0, 1, 2, 0, 2, 3]);
    json!({ "attributes": { "POSITION": p }, "indices": i })
}

/// A scene file including `m.<ext>` with the include keys `extra`, lit by a spot, contact cuts
/// off (so polygons stay as the file gives them).
fn scene_text(ext: &str, extra: &str) -> String {
    format!(
        "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov_y = 60\n\n\
         [radiosity]\ncut_contacts = false\nmerge_triangles = false\n\n\
         [[materials]]\nname = \"grey\"\nreflectance = [0.5, 0.5, 0.5]\n\n\
         [[gltf]]\nfile = \"m.{ext}\"\ndefault_material = \"grey\"\n{extra}\n\n\
         [[spots]]\nposition = [0, 5, 1]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\n\
         half_angle = 80\n"
    )
}

/// The in-memory reader of `files` (names relative to `/virtual`).
fn reader(files: &[(&str, Vec<u8>)]) -> impl Fn(&Path) -> std::io::Result<Vec<u8>> {
    let map: BTreeMap<PathBuf, Vec<u8>> = files
        .iter()
        .map(|(n, b)| (Path::new("/virtual").join(n), b.clone()))
        .collect();
    move |p: &Path| {
        map.get(p).cloned().ok_or_else(|| {
            std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory")
        })
    }
}

/// Loads `scene` as `/virtual/s.toml` with the included files `files`.
fn load(scene: &str, files: &[(&str, Vec<u8>)]) -> Result<Scene, Error> {
    parse_scene_with_bytes(scene, Path::new("/virtual/s.toml"), &reader(files))
}

/// Loads a scene including the `.gltf` of `doc` and `nodes`/`meshes` etc. in `body`.
fn load_gltf(doc: &Doc, body: Value, extra: &str) -> Scene {
    load(&scene_text("gltf", extra), &[("m.gltf", doc.gltf(body))]).unwrap()
}

/// The message of the input error of loading `files` with the include `m.<ext>`.
fn error_of(ext: &str, files: &[(&str, Vec<u8>)]) -> String {
    match load(&scene_text(ext, ""), files) {
        Err(e) => {
            assert_eq!(e.exit_code(), EXIT_BAD_INPUT, "{e}");
            assert!(matches!(e, Error::Input { .. }), "{e:?}");
            e.to_string()
        }
        Ok(_) => panic!("loaded"),
    }
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-6
}

fn assert_corners(scene: &Scene, polygon: usize, want: [[f64; 3]; 3]) {
    let got = scene.polygons[polygon].vertices();
    for (g, w) in got.iter().zip(want) {
        assert!(close(*g, DVec3::from_array(w)), "{got:?} != {want:?}");
    }
}

#[test]
fn a_translated_and_scaled_quad_is_placed_vertex_by_vertex() {
    let mut doc = Doc::default();
    let prim = quad(&mut doc);
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }],
        "nodes": [{ "name": "Quad", "mesh": 0, "translation": [1, 2, 3], "scale": [2, 3, 1] }],
        "meshes": [{ "name": "Plane", "primitives": [prim] }]
    });
    let s = load_gltf(&doc, body.clone(), "");
    assert_eq!(s.polygons.len(), 2);
    // p -> (1, 2, 3) + (2, 3, 1) * p, triangle (0 1 2) then (0 2 3), fronts +z.
    assert_corners(&s, 0, [[1.0, 2.0, 3.0], [3.0, 2.0, 3.0], [3.0, 5.0, 3.0]]);
    assert_corners(&s, 1, [[1.0, 2.0, 3.0], [3.0, 5.0, 3.0], [1.0, 5.0, 3.0]]);
    assert_eq!(s.polygons[0].normal, DVec3::Z);
    assert_eq!(s.objects[s.polygons[0].object as usize], "m/Quad");
    assert_eq!(s.material_of(0).name, "grey");
    assert!(s
        .origin(1)
        .contains("meshes[0].primitives[0] triangle 1 (node `Quad`)"));
    assert_eq!(
        s.inputs,
        [Path::new("/virtual/s.toml"), Path::new("/virtual/m.gltf")]
    );
    // The include's transform comes after the node's: rotated 90 degrees about y, then moved.
    let s = load_gltf(&doc, body, "rotate = [0, 90, 0]\ntranslate = [10, 0, 0]");
    // (3, 2, 3) turned about y by 90 degrees is (3, 2, -3); moved, (13, 2, -3).
    assert!(close(s.polygons[0].corners[1], DVec3::new(13.0, 2.0, -3.0)));
    assert!(close(s.polygons[0].normal, DVec3::X));
}

#[test]
fn a_rotated_node_turns_its_mesh_and_parents_compose() {
    let mut doc = Doc::default();
    let prim = quad(&mut doc);
    let h = std::f32::consts::FRAC_1_SQRT_2;
    // The parent turns 90 degrees about y (+z to +x), the child is moved along the parent's x
    // by 2 and given as a matrix (column-major) doubling its z.
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }],
        "nodes": [
            { "name": "Parent", "rotation": [0, h, 0, h], "children": [1] },
            { "name": "Child", "mesh": 0,
              "matrix": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 2, 0,  2, 0, 0, 1] }
        ],
        "meshes": [{ "primitives": [prim] }]
    });
    let s = load_gltf(&doc, body, "");
    // Child point p -> (p.x + 2, p.y, 2 p.z); the parent maps (x, y, z) to (z, y, -x).
    assert_corners(
        &s,
        0,
        [[0.0, 0.0, -2.0], [0.0, 0.0, -3.0], [0.0, 1.0, -3.0]],
    );
    assert!(close(s.polygons[0].normal, DVec3::X));
    assert_eq!(s.objects[s.polygons[0].object as usize], "m/Child");
}

#[test]
fn a_mirroring_scale_reverses_the_corner_order() {
    let mut doc = Doc::default();
    let p = doc.positions(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let body = |scale: [f32; 3]| {
        json!({
            "scene": 0, "scenes": [{ "nodes": [0] }],
            "nodes": [{ "mesh": 0, "scale": scale }],
            "meshes": [{ "primitives": [{ "attributes": { "POSITION": p } }] }]
        })
    };
    // Mirrored in x by the node: the corners (0,0,0) (-1,0,0) (0,1,0) reversed, front still +z.
    let s = load_gltf(&doc, body([-1.0, 1.0, 1.0]), "");
    assert_corners(&s, 0, [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]);
    assert_eq!(s.polygons[0].normal, DVec3::Z);
    assert_eq!(s.objects[0], "m/nodes[0]");
    // Mirrored by the node and by the include: not mirrored, corners in file order.
    let s = load_gltf(&doc, body([-1.0, 1.0, 1.0]), "scale = [-1, 1, 1]");
    assert_corners(&s, 0, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    assert_eq!(s.polygons[0].normal, DVec3::Z);
    // Mirrored by the include alone (z): reversed, front -z (the mirror image's front).
    let s = load_gltf(&doc, body([1.0, 1.0, 1.0]), "scale = [1, 1, -1]");
    assert_corners(&s, 0, [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]);
    assert_eq!(s.polygons[0].normal, DVec3::NEG_Z);
}

/// One quad of material 0 of `materials`.
fn with_materials(materials: Value) -> (Doc, Value) {
    let mut doc = Doc::default();
    let mut prim = quad(&mut doc);
    prim["material"] = json!(0);
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }],
        "nodes": [{ "name": "Panel", "mesh": 0 }],
        "meshes": [{ "primitives": [prim] }],
        "materials": materials,
        "extensionsUsed": ["KHR_materials_emissive_strength"]
    });
    (doc, body)
}

#[test]
fn emission_is_the_emissive_factor_times_its_strength() {
    let (doc, body) = with_materials(json!([{
        "name": "Lamp",
        "pbrMetallicRoughness": { "baseColorFactor": [0.8, 0.6, 0.4, 1], "metallicFactor": 0 },
        "emissiveFactor": [0.5, 0.25, 1],
        "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": 4 } }
    }]));
    let s = load_gltf(&doc, body, "");
    let m = s.material_of(0);
    assert_eq!(m.name, "Lamp");
    assert_eq!(m.reflectance, DVec3::new(0.8, 0.6, 0.4));
    assert_eq!(m.emission, DVec3::new(2.0, 1.0, 4.0));
    // One-sided: no twins.
    assert_eq!(s.polygons.len(), 2);
    assert_eq!(s.emitter_count(), 2);
}

#[test]
fn a_double_sided_emitter_gets_twins_and_a_double_sided_wall_does_not() {
    let (doc, body) = with_materials(json!([{
        "name": "Panel", "doubleSided": true, "emissiveFactor": [1, 1, 1],
        "pbrMetallicRoughness": { "baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0 }
    }]));
    let s = load_gltf(&doc, body, "");
    assert_eq!(s.polygons.len(), 4);
    assert_eq!(s.polygons[0].normal, DVec3::Z);
    assert_eq!(s.polygons[1].normal, DVec3::NEG_Z);
    assert_eq!(s.polygons[1].vertices()[0], s.polygons[0].vertices()[0]);
    assert!(s
        .notes
        .iter()
        .any(|n| n.contains("2 polygons of two-sided materials")));
    let (doc, body) = with_materials(json!([{
        "name": "Wall", "doubleSided": true,
        "pbrMetallicRoughness": { "baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0 }
    }]));
    assert_eq!(load_gltf(&doc, body, "").polygons.len(), 2);
}

#[test]
fn a_white_base_colour_is_clamped_and_textures_are_noted() {
    let (doc, mut body) = with_materials(json!([{
        "name": "grey",
        "pbrMetallicRoughness": { "baseColorFactor": [1, 1, 1, 1],
                                  "baseColorTexture": { "index": 0 } }
    }]));
    body["textures"] = json!([{ "source": 0 }]);
    body["images"] = json!([{ "uri": "wood.png" }]);
    let s = load_gltf(&doc, body.clone(), "");
    let m = s.material_of(0);
    // The name is the scene's already: renamed after the file.
    assert_eq!(m.name, "m/grey");
    assert_eq!(m.reflectance, DVec3::splat(crate::MAX_OBJ_REFLECTANCE));
    assert!(
        s.warnings.iter().any(|w| w.contains(
            "m.gltf: materials[0].pbrMetallicRoughness.baseColorFactor: [1, 1, 1] is 1 or more"
        )),
        "{:?}",
        s.warnings
    );
    let note = s
        .notes
        .iter()
        .find(|n| n.contains("material `grey`"))
        .expect("a note");
    assert!(
        note.contains("baseColorTexture: texture ignored, its factor used"),
        "{note}"
    );
    // glTF's default metalness is 1: said too.
    assert!(note.contains("metallicFactor 1"), "{note}");
    // `--strict` refuses the white instead.
    let opts = LoadOptions {
        strict: true,
        ..Default::default()
    };
    let read = reader(&[("m.gltf", doc.gltf(body))]);
    let text = |p: &Path| read(p).map(|b| String::from_utf8(b).unwrap());
    let readers = Readers {
        text: &text,
        bytes: &read,
        limit: base::output::MAX_INPUT_BYTES,
    };
    let e = parse_scene_options(
        &scene_text("gltf", ""),
        Path::new("/virtual/s.toml"),
        readers,
        &opts,
    )
    .err()
    .expect("refused");
    assert!(
        e.to_string().contains("baseColorFactor: component 0 is 1"),
        "{e}"
    );
}

#[test]
fn the_materials_table_maps_gltf_names_to_scene_materials() {
    let (doc, body) = with_materials(json!([{ "name": "Lamp", "emissiveFactor": [1, 1, 1] }]));
    let s = load_gltf(&doc, body.clone(), "materials = { Lamp = \"grey\" }");
    assert_eq!(s.material_of(0).name, "grey");
    assert_eq!(s.materials.len(), 1);
    let e = load(
        &scene_text("gltf", "materials = { Lump = \"grey\" }"),
        &[("m.gltf", doc.gltf(body))],
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        e.contains("gltf[0].materials.Lump: the glTF has no material `Lump`"),
        "{e}"
    );
}

#[test]
fn strips_and_fans_become_triangles_and_lines_are_skipped() {
    let mut doc = Doc::default();
    let p = doc.positions(&[
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
    ]);
    let f = doc.positions(&[
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
    ]);
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [
            { "attributes": { "POSITION": p }, "mode": 5 },
            { "attributes": { "POSITION": f }, "mode": 6 },
            { "attributes": { "POSITION": p }, "mode": 1 }
        ] }]
    });
    let s = load_gltf(&doc, body, "");
    // Strip: (0 1 2) and (1 3 2); fan (a square at z = 1): (1 2 0) and (2 3 0); all fronts +z.
    assert_eq!(s.polygons.len(), 4);
    assert_corners(&s, 1, [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]);
    assert_corners(&s, 2, [[1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 0.0, 1.0]]);
    assert!(s.polygons.iter().all(|q| q.normal == DVec3::Z));
    assert!(
        s.notes
            .iter()
            .any(|n| n.contains("meshes[0].primitives[2]: mode Lines") && n.contains("skipped")),
        "{:?}",
        s.notes
    );
}

#[test]
fn a_glb_and_a_gltf_with_a_bin_file_load_like_the_data_uri() {
    let mut doc = Doc::default();
    let prim = quad(&mut doc);
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0, "translation": [0.25, 0.5, 0.75] }],
        "meshes": [{ "primitives": [prim] }]
    });
    let uri = load_gltf(&doc, body.clone(), "");
    // Positions without their bounds (which glTF requires) load all the same.
    let mut unbounded = doc.clone();
    for k in ["min", "max"] {
        unbounded.accessors[0].as_object_mut().unwrap().remove(k);
    }
    assert_eq!(
        load_gltf(&unbounded, body.clone(), "").polygons,
        uri.polygons
    );
    let glb = load(&scene_text("glb", ""), &[("m.glb", doc.glb(body.clone()))]).unwrap();
    assert_eq!(glb.polygons, uri.polygons);
    let (text, bin) = doc.gltf_and_bin(body, "m%20data.bin");
    let files = [("m.gltf", text), ("m data.bin", bin)];
    let bin = load(&scene_text("gltf", ""), &files).unwrap();
    assert_eq!(bin.polygons, uri.polygons);
    assert_eq!(bin.inputs.last().unwrap(), Path::new("/virtual/m data.bin"));
}

/// The `nodes` array of a document.
fn nodes(body: &mut Value) -> &mut Vec<Value> {
    body["nodes"].as_array_mut().expect("nodes")
}

/// A document of one quad node, and the quad's mesh JSON, for the error tests to break.
fn one_quad() -> (Doc, Value) {
    let mut doc = Doc::default();
    let prim = quad(&mut doc);
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [prim] }]
    });
    (doc, body)
}

#[test]
fn a_truncated_glb_is_named_and_does_not_panic() {
    let (doc, body) = one_quad();
    let glb = doc.glb(body);
    let e = error_of("glb", &[("m.glb", glb[..glb.len() - 10].to_vec())]);
    assert!(
        e.starts_with("/virtual/m.glb: is a truncated GLB: its header gives"),
        "{e}"
    );
    let e = error_of("glb", &[("m.glb", glb[..7].to_vec())]);
    assert!(e.contains("shorter than the 12-byte header"), "{e}");
    // The header's length kept, a chunk cut short.
    let mut cut = glb.clone();
    cut.truncate(40);
    cut[8..12].copy_from_slice(&40u32.to_le_bytes());
    let e = error_of("glb", &[("m.glb", cut)]);
    assert!(e.contains("truncated GLB: its Json chunk declares"), "{e}");
}

#[test]
fn an_index_beyond_the_positions_names_the_primitive() {
    let mut doc = Doc::default();
    let p = doc.positions(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let i = doc.indices(&[0, 1, 5]);
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": p }, "indices": i }] }]
    });
    let e = error_of("gltf", &[("m.gltf", doc.gltf(body))]);
    assert_eq!(
        e,
        "/virtual/m.gltf: meshes[0].primitives[0].indices: element 2 of accessors[1] is 5, \
         beyond the primitive's 3 positions"
    );
}

/// gltf-json's check of POSITION's bounds indexed the accessors before their indices were
/// checked, and panicked on one past the end (found by `a_damaged_glb_never_panics`).
#[test]
fn a_position_accessor_that_does_not_exist_is_an_error_not_a_panic() {
    let mut doc = Doc::default();
    let _ = doc.positions(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 7 } }] }]
    });
    let e = error_of("gltf", &[("m.gltf", doc.gltf(body))]);
    assert!(
        e.starts_with("/virtual/m.gltf: meshes[0].primitives[0].attributes.POSITION: accessor 7 does not exist"),
        "{e}"
    );
}

#[test]
fn an_accessor_beyond_its_view_names_the_attribute() {
    let (mut doc, body) = one_quad();
    doc.accessors[0]["count"] = json!(5);
    let e = error_of("gltf", &[("m.gltf", doc.gltf(body.clone()))]);
    assert!(
        e.starts_with(
            "/virtual/m.gltf: meshes[0].primitives[0].attributes.POSITION: accessors[0] (5 \
             elements of 12 bytes"
        ) && e.contains("reads beyond the 48 bytes of bufferViews[0]"),
        "{e}"
    );
    // A view beyond its buffer.
    let (mut doc, body) = one_quad();
    doc.views[1]["byteOffset"] = json!(60);
    let e = error_of("gltf", &[("m.gltf", doc.gltf(body))]);
    assert!(
        e.contains("meshes[0].primitives[0].indices: bufferViews[1] (bytes 60 + 12) lies beyond"),
        "{e}"
    );
}

#[test]
fn a_missing_bin_file_names_the_buffer() {
    let (doc, body) = one_quad();
    let (text, _) = doc.gltf_and_bin(body, "gone.bin");
    let e = error_of("gltf", &[("m.gltf", text)]);
    assert!(
        e.starts_with(
            "/virtual/m.gltf: buffers[0].uri: cannot read buffer file /virtual/gone.bin: No such"
        ),
        "{e}"
    );
    // A GLB whose buffer has no URI and no binary chunk.
    let (doc, body) = one_quad();
    let glb = doc.glb(body);
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut no_bin = glb[..20 + json_len].to_vec();
    let total = no_bin.len() as u32;
    no_bin[8..12].copy_from_slice(&total.to_le_bytes());
    let e = error_of("glb", &[("m.glb", no_bin)]);
    assert!(
        e.contains("buffers[0]: has no `uri`") && e.contains("the file has none"),
        "{e}"
    );
}

#[test]
fn non_finite_positions_and_broken_references_are_refused() {
    let mut doc = Doc::default();
    let p = doc.positions(&[[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": p } }] }]
    });
    let e = error_of("gltf", &[("m.gltf", doc.gltf(body))]);
    assert_eq!(
        e,
        "/virtual/m.gltf: meshes[0].primitives[0].attributes.POSITION: element 1 of \
         accessors[0] is [NaN, 0.0, 0.0]: positions must be finite"
    );
    let (doc, mut body) = one_quad();
    body["nodes"][0]["mesh"] = json!(7);
    let e = error_of("gltf", &[("m.gltf", doc.gltf(body))]);
    assert!(
        e.starts_with("/virtual/m.gltf: nodes[0].mesh: Index out of bounds"),
        "{e}"
    );
    let (doc, mut body) = one_quad();
    body["nodes"][0]["children"] = json!([0]);
    let e = error_of("gltf", &[("m.gltf", doc.gltf(body))]);
    assert!(
        e.starts_with("/virtual/m.gltf: nodes[0]: is reached twice"),
        "{e}"
    );
    let broken = b"{\n  \"asset\": { \"version\": \"2.0\" },\n  \"nodes\": [{ \"mesh\": }]\n}";
    let e = error_of("gltf", &[("m.gltf", broken.to_vec())]);
    assert!(
        e.starts_with("/virtual/m.gltf:3: the file is not glTF 2.0 JSON"),
        "{e}"
    );
    let (doc, mut body) = one_quad();
    body["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    let e = error_of("gltf", &[("m.gltf", doc.gltf(body))]);
    assert!(e.contains("extensionsRequired[0]: `KHR_draco_mesh_compression` is required"));
}

/// A node holding light 0 of `lights`, at (0, 3, 0) turned so its -z axis points down.
fn lit(lights: Value) -> Scene {
    let (doc, mut body) = one_quad();
    let s = std::f32::consts::FRAC_1_SQRT_2;
    body["scenes"][0]["nodes"] = json!([0, 1]);
    nodes(&mut body).push(json!({
        "name": "Lamp", "translation": [0, 3, 0], "rotation": [-s, 0, 0, s],
        "extensions": { "KHR_lights_punctual": { "light": 0 } }
    }));
    body["extensions"] = json!({ "KHR_lights_punctual": { "lights": lights } });
    body["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    load_gltf(&doc, body, "")
}

#[test]
fn a_spot_light_keeps_its_place_axis_cone_and_power() {
    let s = lit(json!([{
        "name": "Key", "type": "spot", "intensity": 100, "color": [1, 0.5, 0.25],
        "spot": { "innerConeAngle": 0.25, "outerConeAngle": 0.5 }
    }]));
    // The scene's own spot first, then the glTF's.
    assert_eq!(s.spots.len(), 2);
    let l = &s.spots[1];
    assert!(close(l.position, DVec3::new(0.0, 3.0, 0.0)));
    assert!(close(l.direction, DVec3::NEG_Y));
    let i = 100.0 / std::f64::consts::PI;
    assert!(close(l.intensity, DVec3::new(i, 0.5 * i, 0.25 * i)));
    assert_eq!(l.half_angle, 0.5);
    assert_eq!(l.falloff, cone_falloff(0.25, 0.5));
    assert!(l.falloff > 0.0);
    assert_eq!(
        s.spot_location(1).to_string(),
        "/virtual/m.gltf: nodes[1] light `Key`"
    );
    assert!(s
        .spot_location(0)
        .to_string()
        .starts_with("/virtual/s.toml:"));
}

#[test]
fn a_point_light_is_two_hemispheres_and_a_sun_is_skipped() {
    let s = lit(json!([{ "name": "Bulb", "type": "point", "intensity": 10, "range": 5 }]));
    assert_eq!(s.spots.len(), 3);
    for (l, d) in s.spots[1..].iter().zip([DVec3::Y, DVec3::NEG_Y]) {
        assert!(close(l.position, DVec3::new(0.0, 3.0, 0.0)));
        assert_eq!(l.direction, d);
        assert_eq!(l.half_angle, std::f64::consts::FRAC_PI_2);
        assert_eq!(l.falloff, 0.0);
        assert!(close(
            l.intensity,
            DVec3::splat(10.0 / std::f64::consts::PI)
        ));
    }
    assert!(s
        .notes
        .iter()
        .any(|n| n.contains("light `Bulb`: `range` ignored")));
    let s = lit(json!([{ "name": "Sun", "type": "directional", "intensity": 3 }]));
    assert_eq!(s.spots.len(), 1);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("nodes[1] light `Sun`: a directional light")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn the_spot_falloff_matches_the_gltf_spots_power() {
    // Integrate both intensity profiles over the sphere (midpoint rule in cos theta).
    for (inner, outer) in [
        (0.0, 0.5),
        (0.25, 0.5),
        (0.4, 1.2),
        (1.0, std::f64::consts::FRAC_PI_2),
    ] {
        let n = cone_falloff(inner, outer);
        let (ci, co) = (f64::cos(inner), f64::cos(outer));
        let steps = 200_000;
        let (mut gltf, mut scene) = (0.0, 0.0);
        for k in 0..steps {
            let c = co + (1.0 - co) * (k as f64 + 0.5) / steps as f64;
            let t = ((c - co) / (ci - co)).clamp(0.0, 1.0);
            gltf += t * t;
            scene += c.powf(n);
        }
        assert!(
            (gltf - scene).abs() < 1e-6 * gltf,
            "{inner} {outer}: {gltf} vs {scene}"
        );
    }
    assert_eq!(cone_falloff(0.5, 0.5), 0.0);
}

#[test]
fn the_first_camera_is_offered_with_its_pose_and_field() {
    let (doc, mut body) = one_quad();
    let h = std::f32::consts::FRAC_1_SQRT_2;
    body["scenes"][0]["nodes"] = json!([0, 1, 2]);
    nodes(&mut body).push(json!({
        "name": "Cam", "camera": 0, "translation": [1, 2, 3], "rotation": [0, h, 0, h]
    }));
    nodes(&mut body).push(json!({ "camera": 1, "translation": [9, 9, 9] }));
    body["cameras"] = json!([
        { "name": "Main", "type": "perspective",
          "perspective": { "yfov": 0.5, "aspectRatio": 1.5, "znear": 0.1 } },
        { "type": "orthographic",
          "orthographic": { "xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10 } }
    ]);
    let read = reader(&[("m.gltf", doc.gltf(body))]);
    let text = |p: &Path| read(p).map(|b| String::from_utf8(b).unwrap());
    let readers = Readers {
        text: &text,
        bytes: &read,
        limit: base::output::MAX_INPUT_BYTES,
    };
    let parsed = parse_scene_options(
        &scene_text("gltf", ""),
        Path::new("/virtual/s.toml"),
        readers,
        &LoadOptions::default(),
    )
    .unwrap();
    let c = parsed.camera.expect("a camera");
    // Turned 90 degrees about y, the camera's -z axis is -x.
    assert!(close(c.camera.eye, DVec3::new(1.0, 2.0, 3.0)));
    assert!(close(c.camera.look_at, DVec3::new(0.0, 2.0, 3.0)));
    assert!(close(c.camera.up, DVec3::Y));
    match c.camera.projection {
        crate::Projection::Perspective { fov_y_deg } => {
            assert!((fov_y_deg - 0.5f64.to_degrees()).abs() < 1e-9)
        }
        p => panic!("{p:?}"),
    }
    assert_eq!(c.aspect, Some(1.5));
    assert_eq!(c.origin, "/virtual/m.gltf: nodes[1] camera `Main`");
    // A scene file keeps its own camera.
    assert_eq!(parsed.scene.camera.eye, DVec3::new(0.0, 0.0, 5.0));
}

#[test]
fn a_bare_glb_looks_through_its_camera_and_lights_with_its_emitters() {
    let dir = std::env::temp_dir().join(format!("pfs-gltf-bare-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (doc, mut body) = with_materials(json!([{
        "name": "Glow", "emissiveFactor": [1, 1, 1],
        "pbrMetallicRoughness": { "baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0 }
    }]));
    body["scenes"][0]["nodes"] = json!([0, 1]);
    nodes(&mut body).push(json!({ "camera": 0, "translation": [0.5, 0.5, 4] }));
    body["cameras"] = json!([{ "type": "perspective",
        "perspective": { "yfov": 0.6, "aspectRatio": 2, "znear": 0.1 } }]);
    let path = dir.join("panel.glb");
    std::fs::write(&path, doc.glb(body)).unwrap();
    let s = crate::load_scene(&path).unwrap();
    assert!(close(s.camera.eye, DVec3::new(0.5, 0.5, 4.0)));
    assert!(close(s.camera.look_at, DVec3::new(0.5, 0.5, 3.0)));
    assert_eq!((s.width, s.height), (1200, 600));
    assert!(s.spots.is_empty(), "no default light: the panel emits");
    assert_eq!(s.spot_origins.len(), 0);
    assert!(
        !s.warnings
            .iter()
            .any(|w| w.contains("no camera") || w.contains("default spot")),
        "{:?}",
        s.warnings
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A closed box of size `size`, faces inward, as 12 triangles, no material.
fn closed_box(doc: &mut Doc, size: [f32; 3]) -> Value {
    let [x, y, z] = size;
    let c = |i: u16| {
        [
            if i & 1 != 0 { x } else { 0.0 },
            if i & 2 != 0 { y } else { 0.0 },
            if i & 4 != 0 { z } else { 0.0 },
        ]
    };
    let p = doc.positions(&(0..8).map(c).collect::<Vec<_>>());
    // Each face counter-clockwise seen from inside.
    let faces: [[u16; 4]; 6] = [
        [0, 1, 3, 2], // z = 0, front +z
        [4, 6, 7, 5], // z = max, front -z
        [0, 4, 5, 1], // y = 0, front +y
        [2, 3, 7, 6], // y = max, front -y
        [0, 2, 6, 4], // x = 0, front +x
        [1, 5, 7, 3], // x = max, front -x
    ];
    let idx: Vec<u16> = faces
        .iter()
        .flat_map(|f| [f[0], f[1], f[2], f[0], f[2], f[3]])
        .collect();
    let i = doc.indices(&idx);
    json!({ "attributes": { "POSITION": p }, "indices": i })
}

#[test]
fn a_room_lying_on_its_back_is_said_to_look_z_up() {
    let body = |prim: Value| {
        json!({
            "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
            "meshes": [{ "primitives": [prim] }]
        })
    };
    let mut doc = Doc::default();
    let prim = closed_box(&mut doc, [4.0, 3.0, 5.0]);
    let s = load_gltf(&doc, body(prim), "");
    assert_eq!(s.polygons.len(), 12);
    assert!(s.polygons.iter().all(|p| p.area > 0.0));
    assert!(
        !s.warnings.iter().any(|w| w.contains("z-up")),
        "{:?}",
        s.warnings
    );
    let mut doc = Doc::default();
    let prim = closed_box(&mut doc, [4.0, 5.0, 3.0]);
    let s = load_gltf(&doc, body(prim), "");
    assert!(
        s.warnings
            .iter()
            .any(|w| w.starts_with("/virtual/m.gltf: looks z-up (43 %")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn base64_decodes_with_and_without_padding() {
    use super::data::decode_base64;
    assert_eq!(decode_base64("TWFu").unwrap(), b"Man");
    assert_eq!(decode_base64("TWE=").unwrap(), b"Ma");
    assert_eq!(decode_base64("TWE").unwrap(), b"Ma");
    assert_eq!(decode_base64("TQ==").unwrap(), b"M");
    assert_eq!(decode_base64("").unwrap(), b"");
    let all: Vec<u8> = (0..=255).collect();
    assert_eq!(decode_base64(&base64(&all)).unwrap(), all);
    assert!(decode_base64("TW!u")
        .unwrap_err()
        .contains("'!' at character 2"));
    assert!(decode_base64("TWFuT").is_err());
}

#[test]
fn the_shipped_room_is_lit_by_its_panel_and_seen_through_its_camera() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/gltf/room.glb");
    let s = crate::load_scene(&path).unwrap();
    // 12 room triangles and the panel's 2, merged into 7 quads (`triangle_pairs`), and the
    // panel's twin (doubleSided and emitting).
    assert_eq!(s.merged.pairs, 7, "{:?}", s.notes);
    assert_eq!(s.polygons.len(), 8, "{:?}", s.notes);
    assert_eq!(s.emitter_count(), 2);
    assert!(s.spots.is_empty());
    let panel = s.materials.iter().find(|m| m.name == "Panel").unwrap();
    assert_eq!(panel.emission, DVec3::splat(10.0));
    assert!(
        !s.warnings.iter().any(|w| w.contains("default spot")),
        "{:?}",
        s.warnings
    );
    assert!(close(s.camera.eye, DVec3::new(0.0, 1.6, 2.2)));
    let view = (s.camera.look_at - s.camera.eye).normalize();
    // Tilted 10 degrees down from -z.
    let down = 10f64.to_radians();
    assert!(
        close(view, DVec3::new(0.0, -down.sin(), -down.cos())),
        "{view}"
    );
    assert_eq!((s.width, s.height), (800, 600));
    assert!(
        s.objects.iter().any(|o| o == "room/Room"),
        "{:?}",
        s.objects
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]
    /// A GLB with bytes changed or cut anywhere loads or is refused; it never panics.
    #[test]
    fn a_damaged_glb_never_panics(
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
    ) {
        let (doc, mut body) = one_quad();
        body["nodes"][0]["rotation"] = json!([0, 0.6, 0, 0.8]);
        let mut glb = doc.glb(body);
        for (at, byte) in edits {
            let i = at.index(glb.len());
            glb[i] = byte;
        }
        if truncate {
            glb.truncate(cut.index(glb.len()));
        }
        let _ = load(&scene_text("glb", ""), &[("m.glb", glb)]);
    }
}

/// `NORMAL` gives the triangles shading frames, turned with the node: a quad whose vertex
/// normals lean along x receives light by them, the triangles sharing them on the diagonal;
/// normals equal to the face's leave it flat, as do normals of the wrong count.
#[test]
fn vertex_normals_become_shading_frames_through_the_node_transform() {
    let lean = |x: f32| {
        let n = glam::Vec3::new(x, 0.0, 1.0).normalize();
        [n.x, n.y, n.z]
    };
    let mut doc = Doc::default();
    let mut prim = quad(&mut doc);
    let n = doc.positions(&[lean(-0.2), lean(0.2), lean(0.2), lean(-0.2)]);
    prim["attributes"]["NORMAL"] = json!(n);
    let half = std::f64::consts::FRAC_1_SQRT_2;
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }],
        // Turned 90 degrees about y: +z becomes +x, +x becomes -z.
        "nodes": [{ "mesh": 0, "rotation": [0.0, half, 0.0, half] }],
        "meshes": [{ "primitives": [prim] }]
    });
    let s = load_gltf(&doc, body, "");
    assert_eq!(s.polygons.len(), 2);
    for p in &s.polygons {
        assert!(p.shading.is_some(), "{p:?}");
        assert!(close(p.normal, DVec3::X));
    }
    // At the corner (0, 0, 0) of the model, now at the origin: lean(-0.2) turned.
    let want = DVec3::new(1.0, 0.0, 0.2).normalize();
    let got = s.polygons[0].shading_normal(DVec3::ZERO);
    assert!(close(got, want), "{got} vs {want}");
    // Along the shared diagonal both triangles give the same normal.
    let mid = 0.5 * (s.polygons[0].corners[0] + s.polygons[0].corners[2]);
    assert!(close(
        s.polygons[0].shading_normal(mid),
        s.polygons[1].shading_normal(mid)
    ));
    // Flat normals: no frame. Too few normals: ignored.
    for normals in [vec![[0.0, 0.0, 1.0f32]; 4], vec![lean(0.2); 3]] {
        let mut doc = Doc::default();
        let mut prim = quad(&mut doc);
        let n = doc.positions(&normals);
        prim["attributes"]["NORMAL"] = json!(n);
        let body = json!({
            "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
            "meshes": [{ "primitives": [prim] }]
        });
        let s = load_gltf(&doc, body, "");
        assert!(s.polygons.iter().all(|p| p.shading.is_none()));
    }
}

/// An emission-only material with a black base colour (what Blender writes for an Emission
/// shader) and glTF's default metalness: nothing reflects either way, so no note about it.
#[test]
fn a_black_emitting_material_draws_no_metalness_note() {
    let mut doc = Doc::default();
    let mut prim = quad(&mut doc);
    prim["material"] = json!(0);
    let body = json!({
        "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [prim] }],
        "materials": [{
            "name": "panel",
            "pbrMetallicRoughness": { "baseColorFactor": [0, 0, 0, 1] },
            "emissiveFactor": [1, 1, 1]
        }]
    });
    let s = load_gltf(&doc, body, "");
    assert_eq!(s.material_of(0).emission, DVec3::ONE);
    assert!(
        !s.notes.iter().any(|n| n.contains("metallicFactor")),
        "{:?}",
        s.notes
    );
}
