//! The glTF 2.0 document of an export, built with `gltf-json` (the `gltf` crate's document
//! model) and one binary buffer.
//!
//! Layout: one buffer; one buffer view per vertex attribute, index list and embedded image,
//! each 4-byte aligned; one mesh per scene object (an OBJ group, an inline polygon), named
//! after it, with one primitive per (material, atlas page) pair, each under a node of the same
//! name, and the scene's camera as a camera node, all in one scene. Application-specific data uses the glTF conventions: the vertex
//! attribute `_POLYGON` (the scene polygon each vertex belongs to, as a float scalar: exact up
//! to 2^24 polygons) and `extras` on materials and the asset.

use std::collections::BTreeMap;

use gltf::json;
use json::validation::Checked::Valid;
use json::validation::USize64;

use base::error::{Error, Result};

/// A camera and where its node puts it: glTF cameras look down their node's -Z with +Y up.
pub struct CameraNode {
    /// The camera (perspective or orthographic).
    pub camera: json::Camera,
    /// The node's translation: the eye.
    pub translation: [f32; 3],
    /// The node's rotation, a unit quaternion (x, y, z, w).
    pub rotation: [f32; 4],
}

/// A document being built and its binary buffer.
pub struct Builder {
    /// The document.
    pub root: json::Root,
    /// The buffer's bytes.
    pub bin: Vec<u8>,
}

/// One primitive's vertices, before they go into the buffer.
#[derive(Debug, Default, Clone)]
pub struct Vertices {
    /// Positions.
    pub position: Vec<[f32; 3]>,
    /// Unit normals.
    pub normal: Vec<[f32; 3]>,
    /// Per texture-coordinate set (0, 1, ...): coordinates.
    pub tex_coords: Vec<Vec<[f32; 2]>>,
    /// Linear colours in [0, 1] (`COLOR_0`), or empty.
    pub colour: Vec<[f32; 3]>,
    /// Application-specific float attributes: the name without its leading underscore (the
    /// document adds it: `POLYGON` is written `_POLYGON`), the type and the values.
    pub custom: Vec<(String, json::accessor::Type, Vec<f32>)>,
    /// Three indices per triangle.
    pub indices: Vec<u32>,
}

/// Largest polygon count `_POLYGON` represents exactly (every integer up to 2^24 is an f32).
pub const MAX_POLYGONS: usize = 1 << 24;

fn components(t: json::accessor::Type) -> usize {
    match t {
        json::accessor::Type::Scalar => 1,
        json::accessor::Type::Vec2 => 2,
        json::accessor::Type::Vec3 => 3,
        _ => 4,
    }
}

impl Builder {
    /// An empty document with its asset information (`extras`: JSON about the export).
    pub fn new(extras: serde_json::Value) -> Result<Builder> {
        let root = json::Root {
            asset: json::Asset {
                generator: Some(format!("pixelflow-sim {}", env!("CARGO_PKG_VERSION"))),
                extras: raw(&extras)?,
                ..Default::default()
            },
            ..Default::default()
        };
        Ok(Builder {
            root,
            bin: Vec::new(),
        })
    }

    /// Appends `bytes` to the buffer as a new view (4-byte aligned).
    pub fn view(
        &mut self,
        bytes: &[u8],
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        })
    }

    /// A float attribute accessor of `count` elements of type `t` (with min and max for
    /// positions, which glTF requires).
    fn floats(
        &mut self,
        values: &[f32],
        t: json::accessor::Type,
        bounds: bool,
    ) -> json::Index<json::Accessor> {
        let n = components(t);
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(json::buffer::Target::ArrayBuffer));
        let (min, max) = if bounds {
            let mut lo = vec![f32::INFINITY; n];
            let mut hi = vec![f32::NEG_INFINITY; n];
            for e in values.chunks_exact(n) {
                for c in 0..n {
                    lo[c] = lo[c].min(e[c]);
                    hi[c] = hi[c].max(e[c]);
                }
            }
            (Some(serde_json::json!(lo)), Some(serde_json::json!(hi)))
        } else {
            (None, None)
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(values.len() / n),
            component_type: Valid(json::accessor::GenericComponentType(
                json::accessor::ComponentType::F32,
            )),
            extensions: None,
            extras: Default::default(),
            type_: Valid(t),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    fn indices(&mut self, indices: &[u32]) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = indices.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(json::buffer::Target::ElementArrayBuffer));
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(indices.len()),
            component_type: Valid(json::accessor::GenericComponentType(
                json::accessor::ComponentType::U32,
            )),
            extensions: None,
            extras: Default::default(),
            type_: Valid(json::accessor::Type::Scalar),
            min: None,
            max: None,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A triangle primitive of `v` drawn with `material`.
    pub fn primitive(
        &mut self,
        v: &Vertices,
        material: json::Index<json::Material>,
    ) -> json::mesh::Primitive {
        use json::accessor::Type;
        use json::mesh::Semantic;
        let flat3 = |a: &[[f32; 3]]| a.iter().flatten().copied().collect::<Vec<f32>>();
        let mut attributes = BTreeMap::new();
        attributes.insert(
            Valid(Semantic::Positions),
            self.floats(&flat3(&v.position), Type::Vec3, true),
        );
        if !v.normal.is_empty() {
            attributes.insert(
                Valid(Semantic::Normals),
                self.floats(&flat3(&v.normal), Type::Vec3, false),
            );
        }
        for (set, uv) in v.tex_coords.iter().enumerate() {
            let flat: Vec<f32> = uv.iter().flatten().copied().collect();
            attributes.insert(
                Valid(Semantic::TexCoords(set as u32)),
                self.floats(&flat, Type::Vec2, false),
            );
        }
        if !v.colour.is_empty() {
            attributes.insert(
                Valid(Semantic::Colors(0)),
                self.floats(&flat3(&v.colour), Type::Vec3, false),
            );
        }
        for (name, t, values) in &v.custom {
            attributes.insert(
                Valid(Semantic::Extras(name.clone())),
                self.floats(values, *t, false),
            );
        }
        json::mesh::Primitive {
            attributes,
            extensions: None,
            extras: Default::default(),
            indices: Some(self.indices(&v.indices)),
            material: Some(material),
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
        }
    }

    /// An unlit material named `name` whose colour is `texture` (at texture coordinate set
    /// `tex_coord`) or, without one, the vertex colours; `extras` keeps what engines that
    /// relight need (the diffuse reflectance).
    pub fn unlit_material(
        &mut self,
        name: &str,
        texture: Option<(json::Index<json::Texture>, u32)>,
        extras: serde_json::Value,
    ) -> Result<json::Index<json::Material>> {
        let material = json::Material {
            name: Some(name.to_string()),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor([1.0; 4]),
                base_color_texture: texture.map(|(index, tex_coord)| json::texture::Info {
                    index,
                    tex_coord,
                    extensions: None,
                    extras: Default::default(),
                }),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(1.0),
                ..Default::default()
            },
            extensions: Some(json::extensions::material::Material {
                unlit: Some(json::extensions::material::Unlit {}),
                // The scene crate reads glTF with more extensions of the same crate (features
                // are unified across the workspace): their fields stay empty here.
                ..Default::default()
            }),
            extras: raw(&extras)?,
            ..Default::default()
        };
        Ok(self.root.push(material))
    }

    /// A texture of PNG bytes: embedded in the buffer (`uri` None) or referenced by `uri`,
    /// filtered linearly with mipmaps and clamped at its edges.
    pub fn png_texture(
        &mut self,
        name: &str,
        png: &[u8],
        uri: Option<String>,
    ) -> json::Index<json::Texture> {
        let (buffer_view, uri, mime_type) = match uri {
            None => (
                Some(self.view(png, None)),
                None,
                Some(json::image::MimeType("image/png".into())),
            ),
            Some(u) => (None, Some(u), None),
        };
        let source = self.root.push(json::Image {
            buffer_view,
            mime_type,
            name: Some(name.to_string()),
            uri,
            extensions: None,
            extras: Default::default(),
        });
        let sampler = self.root.push(json::texture::Sampler {
            mag_filter: Some(Valid(json::texture::MagFilter::Linear)),
            min_filter: Some(Valid(json::texture::MinFilter::LinearMipmapLinear)),
            wrap_s: Valid(json::texture::WrappingMode::ClampToEdge),
            wrap_t: Valid(json::texture::WrappingMode::ClampToEdge),
            ..Default::default()
        });
        self.root.push(json::Texture {
            name: Some(name.to_string()),
            sampler: Some(sampler),
            source,
            extensions: None,
            extras: Default::default(),
        })
    }

    /// Finishes the document: one mesh and one node per object (`meshes`: the object's name
    /// and its primitives, in order), the camera as a node when given, and the buffer
    /// (embedded when `bin_uri` is `None`).
    pub fn finish(
        mut self,
        meshes: Vec<(String, Vec<json::mesh::Primitive>)>,
        camera: Option<CameraNode>,
        bin_uri: Option<String>,
    ) -> (json::Root, Vec<u8>) {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut nodes = Vec::new();
        for (name, primitives) in meshes {
            let mesh = self.root.push(json::Mesh {
                extensions: None,
                extras: Default::default(),
                name: Some(name.clone()),
                primitives,
                weights: None,
            });
            nodes.push(self.root.push(json::Node {
                mesh: Some(mesh),
                name: Some(name),
                ..Default::default()
            }));
        }
        if let Some(c) = camera {
            let camera = self.root.push(c.camera);
            nodes.push(self.root.push(json::Node {
                camera: Some(camera),
                name: Some("camera".into()),
                translation: Some(c.translation),
                rotation: Some(json::scene::UnitQuaternion(c.rotation)),
                ..Default::default()
            }));
        }
        let scene = self.root.push(json::Scene {
            extensions: None,
            extras: Default::default(),
            name: Some("scene".into()),
            nodes,
        });
        self.root.scene = Some(scene);
        self.root.push(json::Buffer {
            byte_length: USize64::from(self.bin.len()),
            name: None,
            uri: bin_uri,
            extensions: None,
            extras: Default::default(),
        });
        self.root.extensions_used = vec!["KHR_materials_unlit".into()];
        (self.root, self.bin)
    }
}

/// `value` as a glTF `extras` member (absent for JSON null).
fn raw(value: &serde_json::Value) -> Result<json::Extras> {
    if value.is_null() {
        return Ok(None);
    }
    let s =
        serde_json::to_string(value).map_err(|e| Error::internal(format!("glTF extras: {e}")))?;
    serde_json::value::RawValue::from_string(s)
        .map(Some)
        .map_err(|e| Error::internal(format!("glTF extras: {e}")))
}

/// The GLB container of a document and its buffer.
pub fn glb(root: &json::Root, bin: Vec<u8>) -> Result<Vec<u8>> {
    let json =
        json::serialize::to_vec(root).map_err(|e| Error::internal(format!("glTF JSON: {e}")))?;
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            // Computed by the writer.
            length: 0,
        },
        json: std::borrow::Cow::Owned(json),
        bin: Some(std::borrow::Cow::Owned(bin)),
    };
    glb.to_vec()
        .map_err(|e| Error::internal(format!("GLB container: {e}")))
}

/// The JSON text of a document (`.gltf`).
pub fn gltf_text(root: &json::Root) -> Result<Vec<u8>> {
    json::serialize::to_vec_pretty(root).map_err(|e| Error::internal(format!("glTF JSON: {e}")))
}
