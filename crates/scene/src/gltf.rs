//! `[[gltf]]` includes and bare `.gltf`/`.glb` models: a glTF 2.0 file turned into scene
//! polygons, materials, objects and spot lights, and its first camera offered to a bare model.
//!
//! The `gltf` crate parses the JSON and splits the GLB container; `data` checks the container's
//! header first, validates the document (every index between objects in range), reads the
//! buffers itself (the GLB's binary chunk, `.bin` files beside the glTF through the loader's
//! reader, base64 `data:` URIs) and reads accessors only after checking that they lie in their
//! buffers. The crate's `import` feature is not used: it would decode images this renderer never
//! shows and read files behind the loader's reader. No file can panic the loader or make it
//! allocate more than the files it read: errors name the file and the glTF key path
//! (`room.glb: meshes[2].primitives[0].attributes.POSITION: ...`), exit code 2.
//!
//! Geometry: the nodes of the default scene (else the first scene, else every root node) are
//! walked depth first, without recursion (a node reached twice is refused: the hierarchy must be
//! a tree), each node's matrix or translation-rotation-scale composed with its parent's, then
//! with the include's own transform (`scale`, `rotate`, `translate`, as `[[obj]]`'s). Every
//! triangle of a primitive of mode TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN (indexed or not)
//! becomes a scene triangle through the loader's face checks; points and lines are skipped with
//! a note, and so are triangles of zero area (strips use them as joints). When the whole
//! transform mirrors (a negative determinant), every triangle's corner order is reversed so its
//! front stays its front. Only positions are read, each `f32` turned into the `f64` nearest its
//! shortest decimal, as OBJ coordinates are. glTF has no quads: a flat wall arrives as
//! triangles, each with its own radiosity quadtree (docs/scene-format.md says what that costs).
//! Each node with a mesh is one scene object, named `<file stem>/<node name>` (the mesh's name,
//! or `nodes[i]`, for a node without one).
//!
//! Materials: `baseColorFactor` (rgb) is the reflectance, clamped below 1 with a warning like an
//! OBJ's `Kd` (`--strict` refuses it); `emissiveFactor` times `emissiveStrength` is the emission,
//! taken as exitance as it stands; a `doubleSided` material that emits is two-sided (its polygons
//! get reversed twins), as modelling tools light both faces of a panel. Names are kept, renamed
//! on a clash as `[[obj]]` materials are; the include's `materials` table maps glTF names to
//! scene materials, and primitives without a material take its `default_material`.
//!
//! Lights (`KHR_lights_punctual`) and the camera are read by `lights`; the light units are
//! converted there (candela over pi, matching the emission's scale).

use super::format::ObjSection;
use super::obj::{clamp_reflectance, decimal, decimal3, default_material, unique_name, Transform};
use super::{Material, Polygon};
use crate::checks::{check_emission, check_reflectance, in_range, Cx, Surfaces};
use base::error::{Error, Location, Result};
use glam::{DAffine3, DMat3, DQuat, DVec3};
use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::rc::Rc;
use toml::Spanned;

mod data;
mod lights;
#[cfg(test)]
mod tests;

pub(crate) use crate::checks::ModelCamera;
use data::{Buffers, Opened};

/// Loads one `[[gltf]]` include, appending to the scene's materials, objects, polygons and
/// (through `cx`) spot lights and camera.
pub(crate) fn include(
    cx: &mut Cx<'_>,
    section: &Spanned<ObjSection>,
    key: &str,
    surfaces: &mut Surfaces,
) -> Result<()> {
    let o = section.get_ref();
    let (path, bytes) = read_gltf(cx, o, key)?;
    let file = data::open(&bytes, &path)?;
    // The document holds what it needs of the file (the parsed JSON, a copy of the GLB's
    // binary chunk): the file's bytes are not kept through the conversion.
    drop(bytes);
    let transform = Transform::of(cx, o, key)?;
    let default_material = default_material(cx, o, key, &surfaces.by_name)?;
    let overrides = overrides(cx, o, key, &file, &surfaces.by_name)?;
    let mut converter = Converter {
        stem: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "gltf".to_string()),
        buffers: Buffers::new(file.gltf.document.buffers().len()),
        file: &file,
        transform,
        overrides,
        default_material,
        imported: BTreeMap::new(),
        object_names: BTreeSet::new(),
        positions: BTreeMap::new(),
        up: UpAxis::default(),
        triangles: 0,
        camera_seen: false,
        noted_skin: false,
    };
    converter.walk(cx, surfaces)?;
    converter.finish(cx);
    Ok(())
}

/// The path of the include's glTF file (relative to the scene file's directory) and its bytes,
/// recorded as an input of the scene.
fn read_gltf(cx: &mut Cx<'_>, o: &ObjSection, key: &str) -> Result<(PathBuf, Vec<u8>)> {
    let path = base::output::folder_of(cx.path).join(o.file.get_ref());
    let bytes = (cx.read_bytes)(&path).map_err(|e| {
        cx.err(
            o.file.span(),
            format!("{key}.file"),
            format!("cannot read glTF file {}: {e}", path.display()),
        )
    })?;
    cx.inputs.push(path.clone());
    Ok((path, bytes))
}

/// The name a glTF material goes by in the include's `materials` table and in the scene: its
/// `name`, or `materials[i]` for one without.
fn material_name(m: &::gltf::Material<'_>, index: usize) -> String {
    m.name()
        .map_or_else(|| format!("materials[{index}]"), str::to_string)
}

/// The include's `materials` map ([`super::obj::overrides`]): every key must name a material of
/// the glTF, every value a scene material.
fn overrides(
    cx: &Cx<'_>,
    o: &ObjSection,
    key: &str,
    file: &Opened,
    by_name: &BTreeMap<String, u32>,
) -> Result<BTreeMap<String, u32>> {
    let names: Vec<String> = file
        .gltf
        .document
        .materials()
        .enumerate()
        .map(|(i, m)| material_name(&m, i))
        .collect();
    let names: BTreeSet<&str> = names.iter().map(String::as_str).collect();
    super::obj::overrides(cx, o, key, (&names, "the glTF"), by_name)
}

/// A node with a mesh: its transform to the glTF's frame, its scene object and its name.
struct Placed {
    world: DAffine3,
    object: u32,
    label: String,
}

/// The triangles of one primitive: its positions (in the node's frame) and the corners of each
/// triangle as indices into them, in glTF winding.
struct Triangles {
    positions: Rc<Vec<DVec3>>,
    triangles: Vec<[usize; 3]>,
}

/// A polygon of this tool's export: its id (`_POLYGON`) and the vertices at its corners.
type ExportedPolygon = (u32, [usize; 4]);

/// Turns the nodes of one glTF file into scene materials, objects, polygons and lights.
struct Converter<'f> {
    file: &'f Opened,
    /// The glTF file's stem, which names its objects and renamed materials.
    stem: String,
    buffers: Buffers,
    /// The include's transform, applied after the nodes' own.
    transform: Transform,
    /// glTF material name -> scene material, from the include's `materials` map.
    overrides: BTreeMap<String, u32>,
    default_material: Option<u32>,
    /// glTF material index -> the scene material made of it.
    imported: BTreeMap<usize, u32>,
    /// The object names given so far in this include.
    object_names: BTreeSet<String>,
    /// The positions of each accessor read so far (a mesh used by many nodes is read once).
    positions: BTreeMap<usize, Rc<Vec<DVec3>>>,
    /// How the model's surfaces face, in the glTF's own frame (the up-axis check).
    up: UpAxis,
    /// Triangles added.
    triangles: usize,
    /// Whether a camera was met (only the first is offered).
    camera_seen: bool,
    /// Whether the note about skins and morph targets was given.
    noted_skin: bool,
}

impl Converter<'_> {
    /// A location in the glTF file.
    fn loc(&self, key: impl Into<String>) -> Location {
        Location::file(&self.file.path).with_key(key)
    }

    /// The nodes the walk starts from: the default scene's, else the first scene's, else every
    /// node that is no node's child (with a note saying which).
    fn roots(&self, cx: &mut Cx<'_>) -> Vec<usize> {
        let doc = &self.file.gltf.document;
        if let Some(s) = doc.default_scene() {
            return s.nodes().map(|n| n.index()).collect();
        }
        let path = self.file.path.display();
        if let Some(s) = doc.scenes().next() {
            if doc.scenes().len() > 1 {
                cx.notes.push(format!(
                    "{path}: no default `scene` among {}: scenes[0] drawn",
                    doc.scenes().len()
                ));
            }
            return s.nodes().map(|n| n.index()).collect();
        }
        let children: BTreeSet<usize> = doc
            .nodes()
            .flat_map(|n| n.children().map(|c| c.index()).collect::<Vec<_>>())
            .collect();
        let roots: Vec<usize> = (0..doc.nodes().len())
            .filter(|i| !children.contains(i))
            .collect();
        if !roots.is_empty() {
            cx.notes.push(format!(
                "{path}: no `scenes`: its {} root nodes drawn",
                roots.len()
            ));
        }
        roots
    }

    /// Walks the node trees from [`Converter::roots`], depth first in file order, visiting each
    /// node with its transform to the glTF's frame.
    fn walk(&mut self, cx: &mut Cx<'_>, surfaces: &mut Surfaces) -> Result<()> {
        let doc = &self.file.gltf.document;
        let mut seen = vec![false; doc.nodes().len()];
        let mut stack: Vec<(usize, DAffine3)> = self
            .roots(cx)
            .into_iter()
            .rev()
            .map(|n| (n, DAffine3::IDENTITY))
            .collect();
        while let Some((n, parent)) = stack.pop() {
            let key = format!("nodes[{n}]");
            let Some(node) = doc.nodes().nth(n) else {
                return Err(Error::input(self.loc(key), "is out of range"));
            };
            if seen.get(n).copied().unwrap_or(true) {
                return Err(Error::input(
                    self.loc(key),
                    "is reached twice (a child of two nodes, or of itself): a glTF's nodes \
                     form trees",
                ));
            }
            seen[n] = true;
            let world = parent * self.local(&node)?;
            self.visit(cx, &node, &world, surfaces)?;
            let children: Vec<usize> = node.children().map(|c| c.index()).collect();
            stack.extend(children.into_iter().rev().map(|c| (c, world)));
        }
        Ok(())
    }

    /// The transform of `node` to its parent's frame: its `matrix` (affine, as glTF requires),
    /// or its translation, rotation (normalised) and scale. Values are read as decimals like
    /// positions; non-finite values are refused.
    fn local(&self, node: &::gltf::Node<'_>) -> Result<DAffine3> {
        let n = node.index();
        match node.transform() {
            ::gltf::scene::Transform::Matrix { matrix } => {
                let key = format!("nodes[{n}].matrix");
                let m = matrix.map(|c| c.map(|x| decimal(f64::from(x))));
                if !m.iter().flatten().all(|x| in_range(*x)) {
                    return Err(Error::input(
                        self.loc(key),
                        format!("has {m:?}; {}", crate::checks::FINITE_RULE),
                    ));
                }
                let last_row = [m[0][3], m[1][3], m[2][3], m[3][3]];
                if last_row != [0.0, 0.0, 0.0, 1.0] {
                    return Err(Error::input(
                        self.loc(key),
                        format!(
                            "has the last row {last_row:?}; a node's matrix is affine (0, 0, 0, 1)"
                        ),
                    ));
                }
                let col = |i: usize| DVec3::new(m[i][0], m[i][1], m[i][2]);
                Ok(DAffine3::from_cols(col(0), col(1), col(2), col(3)))
            }
            ::gltf::scene::Transform::Decomposed {
                translation,
                rotation,
                scale,
            } => {
                let t = decimal3(translation);
                let s = decimal3(scale);
                let r = rotation.map(|x| decimal(f64::from(x)));
                let q = DQuat::from_array(r);
                for (what, ok) in [
                    ("translation", t.to_array().iter().all(|x| in_range(*x))),
                    ("scale", s.to_array().iter().all(|x| in_range(*x))),
                    ("rotation", q.is_finite() && q.length() > 1e-6),
                ] {
                    if !ok {
                        return Err(Error::input(
                            self.loc(format!("nodes[{n}].{what}")),
                            format!(
                                "is not usable ({t}, {r:?}, {s}): values must be finite and \
                                 at most 1e9, a rotation a non-zero quaternion"
                            ),
                        ));
                    }
                }
                Ok(DAffine3::from_scale_rotation_translation(
                    s,
                    q.normalize(),
                    t,
                ))
            }
        }
    }

    /// Adds what `node` holds: its mesh as one object, its light, its camera (the first met).
    fn visit(
        &mut self,
        cx: &mut Cx<'_>,
        node: &::gltf::Node<'_>,
        world: &DAffine3,
        surfaces: &mut Surfaces,
    ) -> Result<()> {
        if (node.skin().is_some() || node.weights().is_some()) && !self.noted_skin {
            self.noted_skin = true;
            cx.notes.push(format!(
                "{}: skins and morph targets are not read: meshes are drawn at rest",
                self.file.path.display()
            ));
        }
        if let Some(mesh) = node.mesh() {
            let label = node
                .name()
                .or(mesh.name())
                .map_or_else(|| format!("nodes[{}]", node.index()), str::to_string);
            let placed = Placed {
                world: *world,
                object: self.object(&label, surfaces),
                label,
            };
            for prim in mesh.primitives() {
                let key = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
                self.add_primitive(cx, &prim, &key, &placed, surfaces)?;
            }
        }
        if let Some(light) = node.light() {
            self.light(cx, node, &light, world)?;
        }
        if let (Some(camera), false) = (node.camera(), self.camera_seen) {
            self.camera_seen = true;
            self.camera(cx, node, camera.index(), world);
        }
        Ok(())
    }

    /// A new object named `<stem>/<label>`, or `<stem>/<label>#k` if this include already
    /// named one so.
    fn object(&mut self, label: &str, surfaces: &mut Surfaces) -> u32 {
        let base = format!("{}/{label}", self.stem);
        let mut name = base.clone();
        let mut k = 1;
        while self.object_names.contains(&name) {
            k += 1;
            name = format!("{base}#{k}");
        }
        self.object_names.insert(name.clone());
        surfaces.add_object(name)
    }

    /// Adds the triangles of one primitive (see the module docs) of the node `placed`, placed by
    /// its transform (to the glTF's frame) and the include's.
    fn add_primitive(
        &mut self,
        cx: &mut Cx<'_>,
        prim: &::gltf::Primitive<'_>,
        key: &str,
        placed: &Placed,
        surfaces: &mut Surfaces,
    ) -> Result<()> {
        let Some(Triangles {
            positions,
            triangles,
        }) = self.triangles(cx, prim, key)?
        else {
            return Ok(());
        };
        let (world, object, label) = (&placed.world, placed.object, &placed.label);
        let material = self.material(cx, prim, key, surfaces)?;
        let local: Vec<DVec3> = positions
            .iter()
            .map(|p| world.transform_point3(*p))
            .collect();
        let placed: Vec<DVec3> = local.iter().map(|p| self.transform.apply(*p)).collect();
        let mirrors = (world.matrix3.determinant() < 0.0) != self.transform.mirrors();
        if let Some(polygons) = self.exported_polygons(cx, prim, key, positions.len())? {
            for (id, [c0, c1, c2, c3]) in polygons {
                let mut corners = vec![placed[c0], placed[c1], placed[c2]];
                if placed[c3] != placed[c2] {
                    corners.push(placed[c3]);
                }
                if mirrors {
                    corners.reverse();
                }
                let loc = self.loc(format!("{key} polygon {id} (node `{label}`)"));
                cx.add_face(&corners, material, object, loc, &mut surfaces.polygons)?;
                self.triangles += 1;
            }
            return Ok(());
        }
        let normals = self.normals(cx, prim, key, positions.len(), world)?;
        let mut degenerate = 0;
        for (t, &[a, b, c]) in triangles.iter().enumerate() {
            let mut corners = [placed[a], placed[b], placed[c]];
            let mut shading = normals.as_ref().map(|n| [n[a], n[b], n[c]]);
            if mirrors {
                corners.reverse();
                if let Some(n) = shading.as_mut() {
                    n.reverse();
                }
            }
            let in_range = corners
                .iter()
                .all(|c| c.to_array().iter().all(|x| in_range(*x)));
            if in_range && Polygon::triangle(corners, material, object).is_none() {
                degenerate += 1;
                continue;
            }
            self.up.add([local[a], local[b], local[c]]);
            let loc = self.loc(format!("{key} triangle {t} (node `{label}`)"));
            let first = surfaces.polygons.len();
            cx.add_face(&corners, material, object, loc, &mut surfaces.polygons)?;
            if let Some(n) = shading {
                crate::shading::shade_pieces(&mut surfaces.polygons[first..], &corners, &n);
            }
            self.triangles += 1;
        }
        if degenerate > 0 {
            cx.notes.push(format!(
                "{}: {degenerate} of its {} triangles have zero area (collinear or repeated \
                 corners): skipped",
                self.loc(key),
                triangles.len()
            ));
        }
        Ok(())
    }

    /// The primitive's vertex normals (`NORMAL`, VEC3 of FLOAT, one per vertex) in the scene's
    /// frame: through the inverse transpose of the node's transform, then the include's.
    /// `None` without them, or when they are not one per vertex of the right type (the
    /// primitive is then flat, as the glTF specification's flat shading has it).
    fn normals(
        &mut self,
        cx: &mut Cx<'_>,
        prim: &::gltf::Primitive<'_>,
        key: &str,
        vertices: usize,
        world: &glam::DAffine3,
    ) -> Result<Option<Vec<DVec3>>> {
        let Some(accessor) = prim.get(&::gltf::Semantic::Normals) else {
            return Ok(None);
        };
        let key = format!("{key}.attributes.NORMAL");
        let Some(n) = data::read_floats(cx, self.file, &mut self.buffers, &accessor, 3, &key)?
        else {
            return Ok(None);
        };
        if n.len() != 3 * vertices {
            return Ok(None);
        }
        let m = world.matrix3.inverse().transpose();
        if !m.is_finite() {
            return Ok(None);
        }
        let transform = &self.transform;
        Ok(Some(
            n.chunks_exact(3)
                .map(|v| transform.normal(m * DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)))
                .collect(),
        ))
    }

    /// The polygons this tool's exports carry (`_POLYGON`, the source polygon of each vertex,
    /// and `TEXCOORD_0`, the vertex's (u, v) in it): per polygon, in id order, the vertices at
    /// its corners (u, v) = (0, 0), (1, 0), (1, 1), (0, 1), which lie on the polygon whatever
    /// its triangles are. `None` when the primitive lacks either attribute or a polygon lacks a
    /// corner: its triangles are read instead.
    fn exported_polygons(
        &mut self,
        cx: &mut Cx<'_>,
        prim: &::gltf::Primitive<'_>,
        key: &str,
        vertices: usize,
    ) -> Result<Option<Vec<ExportedPolygon>>> {
        let ids = prim.get(&::gltf::Semantic::Extras("POLYGON".into()));
        let uvs = prim.get(&::gltf::Semantic::TexCoords(0));
        let (Some(ids), Some(uvs)) = (ids, uvs) else {
            return Ok(None);
        };
        let (file, buffers) = (self.file, &mut self.buffers);
        let ids_key = format!("{key}.attributes._POLYGON");
        let uvs_key = format!("{key}.attributes.TEXCOORD_0");
        let (Some(ids), Some(uvs)) = (
            data::read_floats(cx, file, buffers, &ids, 1, &ids_key)?,
            data::read_floats(cx, file, buffers, &uvs, 2, &uvs_key)?,
        ) else {
            return Ok(None);
        };
        if ids.len() != vertices || uvs.len() != 2 * vertices {
            return Ok(None);
        }
        let mut corners: std::collections::BTreeMap<u32, [Option<usize>; 4]> = Default::default();
        for (v, &id) in ids.iter().enumerate() {
            if id < 0.0 || id.fract() != 0.0 {
                return Ok(None);
            }
            let slot = match (uvs[2 * v], uvs[2 * v + 1]) {
                (0.0, 0.0) => 0,
                (1.0, 0.0) => 1,
                (1.0, 1.0) => 2,
                (0.0, 1.0) => 3,
                _ => continue,
            };
            corners.entry(id as u32).or_default()[slot].get_or_insert(v);
        }
        let mut out = Vec::with_capacity(corners.len());
        for (id, c) in corners {
            // A triangle is exported as itself: its apex is (u, v) = (1, 1) only.
            let [Some(a), Some(b), Some(c2), d] = c else {
                return Ok(None);
            };
            out.push((id, [a, b, c2, d.unwrap_or(c2)]));
        }
        Ok(Some(out))
    }

    /// The triangles of a primitive; `None`, with a note, for a primitive that is not a surface
    /// or has no positions.
    fn triangles(
        &mut self,
        cx: &mut Cx<'_>,
        prim: &::gltf::Primitive<'_>,
        key: &str,
    ) -> Result<Option<Triangles>> {
        use ::gltf::mesh::Mode;
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            cx.notes.push(format!(
                "{}: mode {mode:?}: points and lines are not surfaces: skipped",
                self.loc(key)
            ));
            return Ok(None);
        }
        let Some(accessor) = prim.get(&::gltf::Semantic::Positions) else {
            cx.notes.push(format!(
                "{}: has no POSITION attribute: skipped",
                self.loc(key)
            ));
            return Ok(None);
        };
        let positions = self.positions(cx, &accessor, &format!("{key}.attributes.POSITION"))?;
        let order: Vec<usize> = match prim.indices() {
            Some(acc) => data::read_indices(
                cx,
                self.file,
                &mut self.buffers,
                &acc,
                positions.len(),
                &format!("{key}.indices"),
            )?
            .into_iter()
            .map(|i| i as usize)
            .collect(),
            None => (0..positions.len()).collect(),
        };
        let triangles = assemble(mode, &order);
        if mode == Mode::Triangles && !order.len().is_multiple_of(3) {
            cx.notes.push(format!(
                "{}: {} vertices, not a multiple of 3: the last {} ignored",
                self.loc(key),
                order.len(),
                order.len() % 3
            ));
        }
        Ok(Some(Triangles {
            positions,
            triangles,
        }))
    }

    /// The positions of `accessor`, read once per include.
    fn positions(
        &mut self,
        cx: &mut Cx<'_>,
        accessor: &::gltf::Accessor<'_>,
        key: &str,
    ) -> Result<Rc<Vec<DVec3>>> {
        if let Some(p) = self.positions.get(&accessor.index()) {
            return Ok(Rc::clone(p));
        }
        let p = Rc::new(data::read_positions(
            cx,
            self.file,
            &mut self.buffers,
            accessor,
            key,
        )?);
        self.positions.insert(accessor.index(), Rc::clone(&p));
        Ok(p)
    }

    /// The scene material of a primitive: its glTF material (overridden by the include's
    /// `materials` table, or imported once), else the include's `default_material`.
    fn material(
        &mut self,
        cx: &mut Cx<'_>,
        prim: &::gltf::Primitive<'_>,
        key: &str,
        surfaces: &mut Surfaces,
    ) -> Result<u32> {
        let m = prim.material();
        let Some(index) = m.index() else {
            return self.default_material.ok_or_else(|| {
                Error::input(
                    self.loc(key),
                    "has no material; set `default_material` in the scene's [[gltf]] entry",
                )
            });
        };
        let name = material_name(&m, index);
        if let Some(&idx) = self.overrides.get(&name) {
            return Ok(idx);
        }
        if let Some(&idx) = self.imported.get(&index) {
            return Ok(idx);
        }
        let (reflectance, emission) = self.material_values(cx, &m, index)?;
        let scene_name = unique_name(cx, &self.stem, &name, &surfaces.by_name);
        let idx = surfaces.add_material(Material {
            name: scene_name,
            reflectance,
            emission,
        });
        if m.double_sided() && emission.max_element() > 0.0 {
            surfaces.two_sided.push(idx);
        } else if m.double_sided() {
            surfaces.double_sided.push(idx);
        }
        self.imported.insert(index, idx);
        Ok(idx)
    }

    /// The reflectance (`baseColorFactor`, clamped below 1 unless `--strict`) and emission
    /// (`emissiveFactor` times `emissiveStrength`) of glTF material `index`, checked; what is
    /// not read (textures, metalness) is said in a note.
    fn material_values(
        &self,
        cx: &mut Cx<'_>,
        m: &::gltf::Material<'_>,
        index: usize,
    ) -> Result<(DVec3, DVec3)> {
        let key = format!("materials[{index}]");
        if let Some((reflectance, emission)) = exported_values(m) {
            // An export of this tool: its materials are unlit with a white base colour, the
            // source scene's values kept beside them.
            let loc = || self.loc(format!("{key}.extras.pixelflow"));
            check_reflectance(reflectance).map_err(|msg| Error::input(loc(), msg))?;
            check_emission(emission).map_err(|msg| Error::input(loc(), msg))?;
            return Ok((reflectance, emission));
        }
        let pbr = m.pbr_metallic_roughness();
        let [r, g, b, _] = pbr.base_color_factor();
        let base_loc = self.loc(format!("{key}.pbrMetallicRoughness.baseColorFactor"));
        let reflectance =
            clamp_reflectance(decimal3([r, g, b]), &base_loc, cx.strict, &mut cx.warnings);
        check_reflectance(reflectance).map_err(|msg| Error::input(base_loc, msg))?;
        let strength = m.emissive_strength().map_or(1.0, |s| decimal(f64::from(s)));
        let emission = decimal3(m.emissive_factor()) * strength;
        let finite = emission.to_array().iter().all(|x| in_range(*x));
        check_emission(emission)
            .and_then(|()| {
                finite
                    .then_some(())
                    .ok_or_else(|| crate::checks::FINITE_RULE.to_string())
            })
            .map_err(|msg| {
                Error::input(
                    self.loc(format!("{key}.emissiveFactor")),
                    format!("times emissiveStrength {strength}: {msg}"),
                )
            })?;
        let name = material_name(m, index);
        let mut ignored = Vec::new();
        if pbr.base_color_texture().is_some() {
            ignored.push("baseColorTexture: texture ignored, its factor used".to_string());
        }
        if m.emissive_texture().is_some() {
            ignored.push("emissiveTexture: texture ignored, its factor used".to_string());
        }
        // A black base colour reflects nothing either way (an emission-only material, as
        // Blender writes an Emission shader's): its metallic factor changes nothing to say.
        if pbr.metallic_factor() > 0.5 && reflectance.max_element() > 0.0 {
            ignored.push(format!(
                "metallicFactor {}: drawn as a diffuse surface of its base colour",
                pbr.metallic_factor()
            ));
        }
        if !ignored.is_empty() {
            cx.notes.push(format!(
                "{}: material `{name}`: {} (this renderer draws diffuse colours only)",
                self.loc(key),
                ignored.join("; ")
            ));
        }
        Ok((reflectance, emission))
    }

    /// The include's closing messages: a file that drew nothing, and a model that looks z-up.
    fn finish(&self, cx: &mut Cx<'_>) {
        let path = self.file.path.display();
        if self.triangles == 0 {
            cx.warnings.push(format!(
                "{path}: no triangles drawn (its scene's nodes hold no mesh of triangles)"
            ));
        }
        if let Some(why) = self.up.looks_z_up() {
            cx.warnings.push(format!(
                "{path}: looks z-up ({why}), but glTF is y-up: the model may be lying on its \
                 back. If so, include it from a scene file with `[[gltf]] rotate = [-90, 0, 0]` \
                 (z up becomes y up), or export it with +Y up"
            ));
        }
    }
}

/// The reflectance and emission that this tool's exports keep in a material's
/// `extras.pixelflow` (`reflectance` and `emission`, three finite numbers each), if it has them.
fn exported_values(m: &::gltf::Material<'_>) -> Option<(DVec3, DVec3)> {
    let raw = m.extras().as_ref()?;
    let v: serde_json::Value = serde_json::from_str(raw.get()).ok()?;
    let p = v.get("pixelflow")?;
    let three = |key: &str| -> Option<DVec3> {
        let a = p.get(key)?.as_array()?;
        let x: Vec<f64> = a.iter().filter_map(serde_json::Value::as_f64).collect();
        (x.len() == 3 && a.len() == 3 && x.iter().all(|c| c.is_finite()))
            .then(|| DVec3::new(x[0], x[1], x[2]))
    };
    Some((three("reflectance")?, three("emission")?))
}

/// The triangles a primitive's vertex sequence `order` makes in `mode` (glTF 2.0, section
/// 3.7.2.1): a list in threes (a remainder dropped), a strip (each odd triangle's corners
/// swapped so all keep the first one's winding), or a fan around the first vertex.
fn assemble(mode: ::gltf::mesh::Mode, order: &[usize]) -> Vec<[usize; 3]> {
    use ::gltf::mesh::Mode;
    let n = order.len();
    match mode {
        Mode::Triangles => order.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        Mode::TriangleStrip => (0..n.saturating_sub(2))
            .map(|i| {
                if i % 2 == 0 {
                    [order[i], order[i + 1], order[i + 2]]
                } else {
                    [order[i], order[i + 2], order[i + 1]]
                }
            })
            .collect(),
        Mode::TriangleFan => (0..n.saturating_sub(2))
            .map(|i| [order[i + 1], order[i + 2], order[0]])
            .collect(),
        _ => Vec::new(),
    }
}

/// How much of a model's surface faces each axis, and its bounds, in the glTF's own frame: the
/// evidence for [`UpAxis::looks_z_up`].
#[derive(Default)]
struct UpAxis {
    /// Area of the triangles facing mostly along x, y and z (their normal's largest component).
    area: DVec3,
    lo: Option<DVec3>,
    hi: Option<DVec3>,
}

impl UpAxis {
    /// Counts one triangle.
    fn add(&mut self, [a, b, c]: [DVec3; 3]) {
        let n = (b - a).cross(c - a) * 0.5;
        let m = n.abs();
        if m.x >= m.y && m.x >= m.z {
            self.area.x += m.length();
        } else if m.y >= m.z {
            self.area.y += m.length();
        } else {
            self.area.z += m.length();
        }
        for p in [a, b, c] {
            self.lo = Some(self.lo.map_or(p, |l| l.min(p)));
            self.hi = Some(self.hi.map_or(p, |h| h.max(p)));
        }
    }

    /// Why the model looks z-up, if it does. A y-up model's floors, ceilings and table tops
    /// face ±y; exported z-up they face ±z, and the model is lower along z than it is deep along
    /// y. The rule: the area facing ±z is more than 1.5 times the area facing ±y and more than
    /// 1.2 times the area facing ±x, and the bounds are smaller along z than along y. A room
    /// 4 x 3 x 5 (y up) passes as y-up (its floor and ceiling face y); exported z-up (4 x 5 x 3)
    /// it is caught. Tall y-up objects (a tower) face x and z alike and are not caught. A flat
    /// y-up object facing z (a picture alone) is a false alarm, which the warning allows for.
    fn looks_z_up(&self) -> Option<String> {
        let (lo, hi) = (self.lo?, self.hi?);
        let size = hi - lo;
        let a = self.area;
        let z_up = a.z > 1.5 * a.y && a.z > 1.2 * a.x && size.z < size.y;
        z_up.then(|| {
            let total = (a.x + a.y + a.z).max(f64::MIN_POSITIVE);
            format!(
                "{:.0} % of its surface faces ±z and {:.0} % ±y, and it is {:.3} high along z \
                 against {:.3} along y",
                100.0 * a.z / total,
                100.0 * a.y / total,
                size.z,
                size.y
            )
        })
    }
}

/// The unit direction of the node axis `v` in scene coordinates (the node's `world` transform,
/// then the include's), or `None` if the transforms flatten it.
fn scene_axis(transform: &Transform, world: &DAffine3, v: DVec3) -> Option<DVec3> {
    let m: DMat3 = world.matrix3;
    transform.linear(m * v).try_normalize()
}
