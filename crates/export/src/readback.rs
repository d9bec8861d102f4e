//! Reading a lightmap export back, with the `gltf` crate: the polygons (from the vertices whose
//! texture coordinate set 0 is a corner of the parameter square), each polygon's chart (from
//! its corners' atlas coordinates) and the pages (the embedded or referenced PNGs decoded back
//! to linear radiosity, or the linear OpenEXR pages). What the export's tests draw again with
//! the project's own texture rasterizer, and what a user can check an export with.

use std::collections::BTreeMap;
use std::path::Path;

use glam::{DVec3, Vec3};

use super::atlas::Chart;
use base::error::{Error, Result};
use reconstruction::texture::{MipLevel, Placement, RadiosityTexture, TextureMemory, TextureSet};
use scene::Polygon;

/// Which pages to read back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pages {
    /// The sRGB PNG pages the materials use, decoded and divided by 2^exposure.
    Png,
    /// The linear OpenEXR pages named in the asset's extras.
    Linear,
}

/// A lightmap export, read back.
#[derive(Debug, Clone)]
pub struct Imported {
    /// The polygons, in the order of the scene index in `_POLYGON`, with the material index
    /// the material's extras name.
    pub polygons: Vec<Polygon>,
    /// Each polygon's scene index (ascending; the export leaves the buried polygons out, so
    /// there may be gaps).
    pub ids: Vec<u32>,
    /// Each polygon's chart.
    pub charts: Vec<Chart>,
    /// The gutter the asset's extras give.
    pub gutter: u32,
    /// The exposure the asset's extras give.
    pub exposure: f64,
    /// Linear pages: width, height, texels (row 0 the top).
    pub pages: Vec<(u32, u32, Vec<Vec3>)>,
    /// Per polygon, the bounds of every one of its vertices' lightmap coordinates: least s,
    /// least t, greatest s, greatest t.
    pub uv_bounds: Vec<[f32; 4]>,
}

fn bad(path: &Path, what: impl Into<String>) -> Error {
    Error::input(base::error::Location::file(path), what.into())
}

/// One polygon's corners as found: parameter corner k at `corners[k]`, and its atlas
/// coordinates.
#[derive(Clone)]
struct Found {
    corners: [Option<(DVec3, [f32; 2])>; 4],
    page: u32,
    material: u32,
    bounds: [f32; 4],
}

impl Default for Found {
    fn default() -> Found {
        Found {
            corners: [None; 4],
            page: 0,
            material: 0,
            bounds: [
                f32::INFINITY,
                f32::INFINITY,
                f32::NEG_INFINITY,
                f32::NEG_INFINITY,
            ],
        }
    }
}

/// Reads the lightmap export at `path` (`.glb` or `.gltf`) with its `pages`.
pub fn read(path: &Path, pages: Pages) -> Result<Imported> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| bad(path, format!("not glTF: {e}")))?;
    let folder = &base::output::folder_of(path);
    let buffer = match gltf.blob.clone() {
        Some(b) => b,
        None => {
            let uri = gltf.buffers().next().and_then(|b| match b.source() {
                gltf::buffer::Source::Uri(u) => Some(u.to_string()),
                _ => None,
            });
            let uri = uri.ok_or_else(|| bad(path, "no buffer"))?;
            std::fs::read(folder.join(&uri)).map_err(|e| Error::io(folder.join(uri), e))?
        }
    };
    let extras = asset_extras(&gltf, path)?;
    let gutter = extras["gutter"]
        .as_u64()
        .ok_or_else(|| bad(path, "no gutter in the asset's extras"))? as u32;
    let exposure = extras["exposure"]
        .as_f64()
        .ok_or_else(|| bad(path, "no exposure in the asset's extras"))?;
    let images = read_pages(&gltf, &buffer, folder, &extras, pages, exposure, path)?;
    let found = read_corners(&gltf, &buffer, path)?;
    let ids = found.keys().copied().collect();
    let uv_bounds = found.values().map(|f| f.bounds).collect();
    let mut polygons = Vec::with_capacity(found.len());
    let mut charts = Vec::with_capacity(found.len());
    for (&p, f) in &found {
        let corner =
            |k: usize| f.corners[k].ok_or_else(|| bad(path, format!("polygon {p} lacks a corner")));
        let [c0, c1, c2] = [corner(0)?, corner(1)?, corner(2)?];
        // A triangle is drawn as itself: its apex is (u, v) = (1, 1) only.
        let c3 = f.corners[3].unwrap_or(c2);
        let triangle = c2.0 == c3.0;
        let poly = if triangle {
            Polygon::triangle([c0.0, c1.0, c2.0], f.material, 0)
        } else {
            Polygon::quad([c0.0, c1.0, c2.0, c3.0], f.material, 0)
        };
        polygons.push(poly.ok_or_else(|| bad(path, format!("polygon {p} is degenerate")))?);
        let (w, h, _) = images
            .get(f.page as usize)
            .ok_or_else(|| bad(path, format!("polygon {p} uses a missing page")))?;
        // c1, at (u, v) = (1, 0), is a chart's far corner along its first axis in both
        // layouts, and c3, at (0, 1), along its second (a triangle's apex c3 = c2 is at its
        // affine chart's (0, 1)).
        let width = ((c1.1[0] - c0.1[0]) as f64 * *w as f64).round() as u32;
        let height = ((c3.1[1] - c0.1[1]) as f64 * *h as f64).round() as u32;
        let x = (c0.1[0] as f64 * *w as f64).round() as i64 - gutter as i64;
        let y = (c0.1[1] as f64 * *h as f64).round() as i64 - gutter as i64;
        if x < 0 || y < 0 || width == 0 || height == 0 {
            return Err(bad(
                path,
                format!("polygon {p}'s chart lies outside its page"),
            ));
        }
        charts.push(Chart {
            page: f.page,
            x: x as u32,
            y: y as u32,
            width,
            height,
            triangle,
        });
    }
    Ok(Imported {
        polygons,
        ids,
        charts,
        gutter,
        exposure,
        pages: images,
        uv_bounds,
    })
}

fn asset_extras(gltf: &gltf::Gltf, path: &Path) -> Result<serde_json::Value> {
    let raw = gltf
        .document
        .as_json()
        .asset
        .extras
        .as_ref()
        .ok_or_else(|| {
            bad(
                path,
                "no pixelflow extras on the asset: not a lightmap export",
            )
        })?;
    let v: serde_json::Value =
        serde_json::from_str(raw.get()).map_err(|e| bad(path, format!("asset extras: {e}")))?;
    Ok(v["pixelflow"].clone())
}

/// The pages as linear texels.
fn read_pages(
    gltf: &gltf::Gltf,
    buffer: &[u8],
    folder: &Path,
    extras: &serde_json::Value,
    pages: Pages,
    exposure: f64,
    path: &Path,
) -> Result<Vec<(u32, u32, Vec<Vec3>)>> {
    let decode = |bytes: &[u8], what: &str| -> Result<(u32, u32, Vec<Vec3>)> {
        let bad_page = |e: String| bad(path, format!("{what}: {e}"));
        Ok(match pages {
            Pages::Png => {
                let (w, h, rgb) = imageio::read::decode_rgb8(bytes).map_err(bad_page)?;
                let scale = (-exposure).exp2() as f32;
                let texels = rgb
                    .iter()
                    .map(|p| Vec3::from_array(p.map(|c| srgb_decode(c as f32 / 255.0))) * scale)
                    .collect();
                (w, h, texels)
            }
            Pages::Linear => {
                let (w, h, rgb) = imageio::read::decode_rgb32f(bytes).map_err(bad_page)?;
                (w, h, rgb.into_iter().map(Vec3::from_array).collect())
            }
        })
    };
    match pages {
        Pages::Png => gltf
            .images()
            .map(|im| match im.source() {
                gltf::image::Source::View { view, .. } => {
                    let start = view.offset();
                    decode(&buffer[start..start + view.length()], "embedded PNG")
                }
                gltf::image::Source::Uri { uri, .. } => {
                    let bytes = std::fs::read(folder.join(uri))
                        .map_err(|e| Error::io(folder.join(uri), e))?;
                    decode(&bytes, uri)
                }
            })
            .collect(),
        Pages::Linear => extras["linear_pages"]
            .as_array()
            .ok_or_else(|| bad(path, "no linear_pages in the asset's extras"))?
            .iter()
            .map(|u| {
                let uri = u.as_str().unwrap_or_default();
                let bytes =
                    std::fs::read(folder.join(uri)).map_err(|e| Error::io(folder.join(uri), e))?;
                decode(&bytes, uri)
            })
            .collect(),
    }
}

/// The sRGB decoding of an encoded value in [0, 1].
fn srgb_decode(x: f32) -> f32 {
    if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// Every polygon's corners (vertices whose set-0 coordinates are a corner of the square), its
/// page (from its material's base colour texture) and its scene material, by `_POLYGON`.
fn read_corners(gltf: &gltf::Gltf, buffer: &[u8], path: &Path) -> Result<BTreeMap<u32, Found>> {
    let mut found: BTreeMap<u32, Found> = BTreeMap::new();
    let get = |_: gltf::Buffer| Some(buffer);
    for mesh in gltf.meshes() {
        for prim in mesh.primitives() {
            let mat = prim.material();
            let page = mat
                .pbr_metallic_roughness()
                .base_color_texture()
                .map(|t| t.texture().source().index() as u32)
                .ok_or_else(|| bad(path, "a primitive's material has no lightmap"))?;
            let material = mat
                .extras()
                .as_ref()
                .and_then(|r| serde_json::from_str::<serde_json::Value>(r.get()).ok())
                .and_then(|v| v["pixelflow"]["material"].as_u64())
                .unwrap_or(0) as u32;
            let reader = prim.reader(get);
            let pos: Vec<[f32; 3]> = reader
                .read_positions()
                .ok_or_else(|| bad(path, "no POSITION"))?
                .collect();
            let uv0: Vec<[f32; 2]> = reader
                .read_tex_coords(0)
                .ok_or_else(|| bad(path, "no TEXCOORD_0"))?
                .into_f32()
                .collect();
            let uv1: Vec<[f32; 2]> = reader
                .read_tex_coords(1)
                .ok_or_else(|| bad(path, "no TEXCOORD_1"))?
                .into_f32()
                .collect();
            let ids = polygon_ids(&prim, buffer, path)?;
            for k in 0..pos.len() {
                let f = found.entry(ids[k]).or_default();
                f.bounds = [
                    f.bounds[0].min(uv1[k][0]),
                    f.bounds[1].min(uv1[k][1]),
                    f.bounds[2].max(uv1[k][0]),
                    f.bounds[3].max(uv1[k][1]),
                ];
                f.page = page;
                f.material = material;
                let corner = match uv0[k] {
                    [0.0, 0.0] => 0,
                    [1.0, 0.0] => 1,
                    [1.0, 1.0] => 2,
                    [0.0, 1.0] => 3,
                    _ => continue,
                };
                f.corners[corner] = Some((Vec3::from_array(pos[k]).as_dvec3(), uv1[k]));
            }
        }
    }
    Ok(found)
}

/// The `_POLYGON` attribute of a primitive.
fn polygon_ids(prim: &gltf::Primitive, buffer: &[u8], path: &Path) -> Result<Vec<u32>> {
    let acc = prim
        .attributes()
        .find(|(s, _)| matches!(s, gltf::Semantic::Extras(n) if n == "POLYGON"))
        .map(|(_, a)| a)
        .ok_or_else(|| bad(path, "no _POLYGON attribute"))?;
    let view = acc
        .view()
        .ok_or_else(|| bad(path, "_POLYGON has no buffer view"))?;
    let start = view.offset() + acc.offset();
    let bytes = &buffer[start..start + 4 * acc.count()];
    Ok(bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u32)
        .collect())
}

impl Imported {
    /// Each polygon's texture cut from its chart (level 0 with its gutter), its mip chain and
    /// coarser gutters rebuilt ([`RadiosityTexture::from_stored_level0`]).
    pub fn textures(&self) -> Result<TextureSet> {
        let g = self.gutter;
        let mut textures = Vec::with_capacity(self.charts.len());
        for c in &self.charts {
            let (w, h, texels) = &self.pages[c.page as usize];
            let (ew, eh) = (c.width + 2 * g, c.height + 2 * g);
            if c.x + ew > *w || c.y + eh > *h {
                return Err(Error::inconsistent("a chart lies outside its page"));
            }
            let mut level = Vec::with_capacity((ew * eh) as usize);
            for r in 0..eh {
                let start = ((c.y + r) * w + c.x) as usize;
                level.extend_from_slice(&texels[start..start + ew as usize]);
            }
            if c.triangle {
                if c.width != c.height {
                    return Err(Error::inconsistent("a triangle's chart is not square"));
                }
                // Back from the affine chart to the (u, v) square the texture methods read.
                level = super::atlas::resample(&level, c.width, g, |u, v| {
                    super::atlas::affine_of_square(u, v)
                });
            }
            textures.push(RadiosityTexture::from_stored_level0(MipLevel {
                width: c.width,
                height: c.height,
                gutter: g,
                texels: level,
            })?);
        }
        let sizes: Vec<(u32, u32)> = self.charts.iter().map(|c| (c.width, c.height)).collect();
        Ok(TextureSet {
            textures,
            memory: TextureMemory::of_sizes(&sizes, g),
            placement: Placement::Centre,
            gutter: g,
        })
    }
}
