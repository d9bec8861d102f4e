//! Scene: the first stage a frame passes through. A validated, immutable description of what is
//! rendered: camera, materials, polygons, spot lights and the settings of every later stage.
//!
//! Invariants every later stage relies on (the loader establishes them; the constructors of this
//! module check them again so a scene built in code is held to the same rules):
//! - every number is finite; reflectance is in [0, 1) per channel, emission >= 0;
//! - every [`Polygon`] is a planar (within [`PLANARITY_TOLERANCE`]), convex triangle or quad with
//!   non-zero area, a unit normal and a valid material index;
//! - every polygon carries the parametric domain (u, v) in [0, 1]^2 through [`Polygon::point`]:
//!   the bilinear map of its four corners. A triangle is stored as a quad whose last corner repeats
//!   the third (`c3 == c2`), so its v = 1 edge collapses onto `c2` (the "collapsed quad" map,
//!   P(u, v) = (1 - v)((1 - u) c0 + u c1) + v c2). Quadtrees, patches and textures all live in this
//!   one domain, whatever the polygon's shape.
//!
//! Geometry is kept in `f64`: the radiosity solver integrates over it and the rasterizer converts to
//! its own fixed-point form. Colours are linear RGB; nothing here knows about sRGB.

#![forbid(unsafe_code)]

use glam::DVec3;

use base::method::{Method, Placement};

pub mod adjacency;
pub mod bvh;
pub mod camera_path;
mod checks;
mod coincident;
pub mod contact;
mod face;
pub mod format;
mod gltf;
mod inside_out;
pub mod junctions;
pub mod load;
mod model;
mod obj;
pub mod orientation;
pub mod overrides;
mod parse;
pub mod seal;
pub mod shading;
pub mod triangle_pairs;
mod triangulate;

pub use load::{load_scene, load_scene_with, LoadOptions};
pub use model::is_model;
pub use obj::MAX_OBJ_REFLECTANCE;
pub use parse::{parse_scene, parse_scene_with, parse_scene_with_bytes};

/// Largest image width or height accepted, in pixels.
pub const MAX_IMAGE_DIM: u32 = 16384;

/// A quad whose fourth corner is farther than this from the plane of the first three, relative to
/// the quad's longest diagonal, is not planar: the loader splits it into two triangles with a
/// warning.
pub const PLANARITY_TOLERANCE: f64 = 1e-3;

/// Whether a polygon has three or four distinct corners.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// Three corners; stored with `corners[3] == corners[2]`.
    Triangle,
    /// Four corners, planar and convex.
    Quad,
}

/// A planar convex triangle or quad with its parametric domain.
#[derive(Debug, Clone, PartialEq)]
pub struct Polygon {
    /// Corners in order c0, c1, c2, c3, counter-clockwise seen from the front (the side the normal
    /// points to). (u, v) = (0,0), (1,0), (1,1), (0,1) map to c0, c1, c2, c3.
    pub corners: [DVec3; 4],
    /// Triangle or quad.
    pub shape: Shape,
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// Unit normal (Newell's method over the distinct corners).
    pub normal: DVec3,
    /// Area in square scene units.
    pub area: f64,
    /// Index into [`Scene::objects`]: the inline polygon or OBJ group this came from.
    pub object: u32,
    /// The model's vertex normals where it marks the surface smooth ([`shading`]); `None` for
    /// a flat facet. Shared by the pieces a polygon is cut into.
    pub shading: Option<std::sync::Arc<shading::Shading>>,
    /// Whether faces lie over its front closer than rays resolve ([`seal`]), so that every eye
    /// in front of it sees them instead: the renderers draw it only from behind. Set by the
    /// loader ([`Scene::mark_sealed`]); `Open` for a polygon built in code.
    pub sealed: seal::Sealed,
    /// Whether faces in its plane turned the other way cover it (its two-sided twin, a thin
    /// wall's other side, [`seal::Seals::is_backed`]): from behind, they show instead of it,
    /// where the two would tie in depth. Set by the loader ([`Scene::mark_sealed`]).
    pub backed: bool,
}

impl Polygon {
    /// Builds a triangle; `None` if it has (near) zero area or a non-finite coordinate.
    pub fn triangle(c: [DVec3; 3], material: u32, object: u32) -> Option<Polygon> {
        Self::build([c[0], c[1], c[2], c[2]], Shape::Triangle, material, object)
    }

    /// Builds a quad without checking planarity or convexity (the loader checks those and says
    /// what is wrong); `None` if it has (near) zero area or a non-finite coordinate.
    pub fn quad(c: [DVec3; 4], material: u32, object: u32) -> Option<Polygon> {
        Self::build(c, Shape::Quad, material, object)
    }

    fn build(corners: [DVec3; 4], shape: Shape, material: u32, object: u32) -> Option<Polygon> {
        if !corners.iter().all(|c| c.is_finite()) {
            return None;
        }
        let n = newell_normal(&corners[..shape.corner_count()]);
        let len = n.length();
        let scale = corners
            .iter()
            .map(|c| (*c - corners[0]).length_squared())
            .fold(0.0, f64::max);
        // Twice the area against the squared size: a sliver this thin is degenerate.
        if len <= 1e-12 * scale || len == 0.0 {
            return None;
        }
        Some(Polygon {
            corners,
            shape,
            material,
            normal: n / len,
            area: 0.5 * len,
            object,
            shading: None,
            sealed: seal::Sealed::Open,
            backed: false,
        })
    }

    /// This polygon with its corners listed the other way round (facing the other way: a
    /// two-sided polygon's twin, a face turned inside out), its (u, v) origin kept at its first
    /// corner, material, object and shading kept; `None` if it cannot be built.
    pub fn reversed(&self) -> Option<Polygon> {
        let c = self.corners;
        let t = match self.shape {
            Shape::Triangle => Polygon::triangle([c[0], c[2], c[1]], self.material, self.object),
            Shape::Quad => Polygon::quad([c[0], c[3], c[2], c[1]], self.material, self.object),
        };
        t.map(|q| q.with_shading(self.shading.clone()))
    }

    /// This polygon with the shading frame `shading` (a piece of a cut keeps its polygon's).
    pub fn with_shading(mut self, shading: Option<std::sync::Arc<shading::Shading>>) -> Polygon {
        self.shading = shading;
        self
    }

    /// The normal a receiver at point `x` of this polygon takes for the cosine of the light it
    /// receives: the interpolated vertex normal of a smooth surface ([`shading`]), else the
    /// facet's [`Polygon::normal`].
    #[inline]
    pub fn shading_normal(&self, x: DVec3) -> DVec3 {
        match &self.shading {
            Some(s) => s.at(x, self.normal),
            None => self.normal,
        }
    }

    /// The distinct corners (3 or 4).
    pub fn vertices(&self) -> &[DVec3] {
        &self.corners[..self.shape.corner_count()]
    }

    /// The point at parameters (u, v) in [0, 1]^2 (bilinear map of the corners).
    #[inline]
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        let [c0, c1, c2, c3] = self.corners;
        (1.0 - v) * ((1.0 - u) * c0 + u * c1) + v * ((1.0 - u) * c3 + u * c2)
    }

    /// Partial derivatives dP/du and dP/dv at (u, v).
    #[inline]
    pub fn tangents(&self, u: f64, v: f64) -> (DVec3, DVec3) {
        let [c0, c1, c2, c3] = self.corners;
        let dpdu = (1.0 - v) * (c1 - c0) + v * (c2 - c3);
        let dpdv = (1.0 - u) * (c3 - c0) + u * (c2 - c1);
        (dpdu, dpdv)
    }

    /// Area element |dP/du x dP/dv| at (u, v): integrating it over [0, 1]^2 gives the area.
    #[inline]
    pub fn area_element(&self, u: f64, v: f64) -> f64 {
        let (a, b) = self.tangents(u, v);
        a.cross(b).length()
    }

    /// Centroid of the distinct corners.
    pub fn centroid(&self) -> DVec3 {
        let vs = self.vertices();
        vs.iter().copied().sum::<DVec3>() / vs.len() as f64
    }

    /// A sphere holding the polygon: its centroid and the largest distance of a corner from it.
    pub fn bounding_sphere(&self) -> (DVec3, f64) {
        let c = self.centroid();
        let r = self
            .vertices()
            .iter()
            .map(|v| (*v - c).length())
            .fold(0.0, f64::max);
        (c, r)
    }
}

impl Shape {
    /// 3 for a triangle, 4 for a quad.
    pub fn corner_count(self) -> usize {
        match self {
            Shape::Triangle => 3,
            Shape::Quad => 4,
        }
    }
}

/// Newell's normal (not normalised; its length is twice the polygon's area for a planar polygon).
pub fn newell_normal(vs: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for i in 0..vs.len() {
        let a = vs[i];
        let b = vs[(i + 1) % vs.len()];
        n += (a - vs[0]).cross(b - vs[0]);
    }
    n
}

/// A diffuse material.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Name, unique in the scene.
    pub name: String,
    /// Diffuse reflectance per channel, in [0, 1).
    pub reflectance: DVec3,
    /// Emitted radiosity (exitance, W/m^2 per channel), >= 0.
    pub emission: DVec3,
}

impl Material {
    /// Whether the material emits light.
    pub fn is_emitter(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

/// A spot light: a point source with a cone.
///
/// Radiant intensity in direction w: I(theta) = intensity * cos(theta)^falloff for
/// theta <= half_angle, and 0 outside the cone, where theta is the angle between w and
/// `direction`.
#[derive(Debug, Clone, PartialEq)]
pub struct SpotLight {
    /// Position of the point source.
    pub position: DVec3,
    /// Unit axis of the cone.
    pub direction: DVec3,
    /// Radiant intensity on the axis, per channel (W/sr), >= 0.
    pub intensity: DVec3,
    /// Cone half-angle in radians, in (0, pi/2].
    pub half_angle: f64,
    /// Exponent of the cos(theta) falloff, >= 0.
    pub falloff: f64,
}

impl SpotLight {
    /// Radiant intensity towards the unit direction `w` from the light.
    #[inline]
    pub fn intensity_towards(&self, w: DVec3) -> DVec3 {
        let c = self.direction.dot(w);
        if c <= 0.0 || c < self.half_angle.cos() {
            return DVec3::ZERO;
        }
        self.intensity * c.powf(self.falloff)
    }
}

/// How the camera projects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Perspective with a vertical field of view in degrees, in (0, 180).
    Perspective {
        /// Vertical field of view, degrees.
        fov_y_deg: f64,
    },
    /// Orthographic with the view's width and height in scene units.
    Orthographic {
        /// Width of the view, scene units.
        width: f64,
        /// Height of the view, scene units.
        height: f64,
    },
}

/// A camera: where it is, where it looks, and how it projects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: DVec3,
    /// A point the camera looks at (distinct from `eye`).
    pub look_at: DVec3,
    /// Up direction (not parallel to the view direction).
    pub up: DVec3,
    /// Projection.
    pub projection: Projection,
}

/// One keyframe of a walkthrough: a camera pose. The projection is the scene camera's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    /// Eye position.
    pub eye: DVec3,
    /// Point looked at.
    pub look_at: DVec3,
    /// Up direction.
    pub up: DVec3,
}

/// An optional camera path for walkthroughs.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraPath {
    /// Keyframes, at least two.
    pub keyframes: Vec<Keyframe>,
    /// Frames rendered along the whole path, >= 2.
    pub frames: u32,
}

/// Smallest `radiosity.tolerance` accepted: the samples are `f32` (a relative precision of
/// 6e-8), and the leaf test compares differences of samples, so a tolerance much below 1e-6
/// cannot be met and would refine every polygon to `max_depth`.
pub const MIN_TOLERANCE: f64 = 1e-6;

/// Smallest `radiosity.convergence` accepted: the light left unshot below it is under what the
/// `f32` samples hold.
pub const MIN_CONVERGENCE: f64 = 1e-7;

/// Settings of the radiosity solve (stage 2).
#[derive(Debug, Clone, PartialEq)]
pub struct RadiositySettings {
    /// Subdivision tolerance, a relative error: a leaf splits when the true reflected radiosity
    /// at a test point differs from the bilinear prediction of its corners by more than
    /// `tolerance` times the leaf's own level, a level never taken below 1 % of the brightest
    /// reflected radiosity (`radiosity::shoot::REFINE_FLOOR`), or when a shadow boundary crosses
    /// it (`docs/scene-format.md`).
    pub tolerance: f64,
    /// Every polygon's quadtree is subdivided at least to this depth.
    pub min_depth: u32,
    /// No leaf is deeper than this (at most [`base::quadtree::MAX_DEPTH`]).
    pub max_depth: u32,
    /// The solve stops when, in every channel, the unshot power falls below this fraction of
    /// the power emitted in that channel.
    pub convergence: f64,
    /// Shadow rays per receiver point and source (stratified over the source).
    pub shadow_rays: u32,
    /// Seed of every pseudo-random choice of the solve.
    pub seed: u64,
    /// How the solver finds which polygons each shooter can reach (`docs/scene-format.md`).
    pub visibility: Visibility,
    /// Whether the loader cuts polygons along their contact lines ([`contact`]): where a
    /// polygon stands on or passes through another, the light of the other steps.
    pub cut_contacts: bool,
    /// Whether the loader merges coplanar triangle pairs of one material into the quads they
    /// form ([`triangle_pairs`]).
    pub merge_triangles: bool,
}

/// How the solver finds the receivers a shooter can reach (`radiosity.visibility`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Visibility {
    /// `exact` for scenes whose shooter-polygon pairs are few enough to test them all
    /// (`radiosity::transfer::EXACT_PAIRS_LIMIT`), `sampled` beyond.
    #[default]
    Auto,
    /// Every (shooter, polygon) pair is classified: cost and memory grow with their product.
    Exact,
    /// The polygons a shooter's probe rays hit, and their neighbours, are its receivers: cost
    /// grows with what each shooter sees (`radiosity::transfer::PROBE_RAYS`).
    Sampled,
}

impl Default for RadiositySettings {
    fn default() -> Self {
        RadiositySettings {
            tolerance: 0.01,
            min_depth: 1,
            max_depth: 7,
            convergence: 0.01,
            shadow_rays: 16,
            seed: 1,
            visibility: Visibility::Auto,
            cut_contacts: true,
            merge_triangles: true,
        }
    }
}

/// Settings of the render (stages 4 to 7).
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSettings {
    /// Method used when the command line names none (`direct`, `texture-bilinear`, ...).
    pub method: Method,
    /// Supersamples per pixel (1 = no antialiasing; checked at load).
    pub aa_samples: base::method::Aa,
    /// Texture size for the texture methods (0 = chosen per polygon from its quadtree depth).
    pub texture_size: u32,
    /// Where the texture methods place their texels (`--texel-placement` overrides it).
    pub texel_placement: Placement,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            method: Method::Direct,
            aa_samples: base::method::Aa::ONE,
            texture_size: 0,
            texel_placement: Placement::Centre,
        }
    }
}

/// How linear radiosity becomes a PNG.
#[derive(Debug, Clone, PartialEq)]
pub struct DisplaySettings {
    /// Exposure in stops: a pixel's radiosity is multiplied by 2^exposure before sRGB encoding.
    pub exposure: f64,
    /// Linear RGB of pixels that see no polygon.
    pub background: DVec3,
}

impl Default for DisplaySettings {
    fn default() -> Self {
        DisplaySettings {
            exposure: 0.0,
            background: DVec3::ZERO,
        }
    }
}

/// A validated scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The file the scene was loaded from (empty for scenes built in code).
    pub source: std::path::PathBuf,
    /// The camera.
    pub camera: Camera,
    /// Image width in pixels, in 1..=[`MAX_IMAGE_DIM`].
    pub width: u32,
    /// Image height in pixels, in 1..=[`MAX_IMAGE_DIM`].
    pub height: u32,
    /// Materials; polygons refer to them by index.
    pub materials: Vec<Material>,
    /// Names of the inline polygons and OBJ groups polygons came from.
    pub objects: Vec<String>,
    /// The polygons.
    pub polygons: Vec<Polygon>,
    /// Spot lights: the `[[spots]]` entries, then the lights of the glTF includes.
    pub spots: Vec<SpotLight>,
    /// Per spot light, where it was written (the `[[spots]]` entry's position, or the glTF node
    /// and light), for messages about it; empty for scenes built in code.
    pub spot_origins: Vec<base::error::Location>,
    /// Radiosity settings.
    pub radiosity: RadiositySettings,
    /// Render settings.
    pub render: RenderSettings,
    /// Display settings.
    pub display: DisplaySettings,
    /// Optional walkthrough path.
    pub camera_path: Option<CameraPath>,
    /// Warnings about what the image will show (a material clamped, a default camera or light
    /// of a model, faces seen or lit from behind, overlapping polygons), for the user to read.
    pub warnings: Vec<String>,
    /// Repairs of the input that change nothing the image shows (a non-planar quad split, a
    /// concave face triangulated, a repeated polygon counted once, a point or line skipped):
    /// `check` lists them, the other commands count them.
    pub notes: Vec<String>,
    /// Every file read to build the scene: the scene file, then its OBJ and MTL files in load
    /// order (empty for scenes built in code). Outputs are checked against these, so that no
    /// job overwrites its own input.
    pub inputs: Vec<std::path::PathBuf>,
    /// Per polygon, where it was written (file, line, key or OBJ face), for messages about
    /// it; empty for scenes built in code.
    pub origins: Vec<base::error::Location>,
    /// The contact lines the loader found and the polygons it cut along them ([`contact`]);
    /// polygon indices in it are those before the cut.
    pub contacts: contact::Cuts,
    /// The triangle pairs the loader merged into quads ([`triangle_pairs`]).
    pub merged: triangle_pairs::Merged,
    /// The polygons the loader cut through T-junctions whose lattices do not line up
    /// ([`junctions`]); polygon indices in it are those before each pass.
    pub junctions: contact::Cuts,
    /// The adjacency the T-junction pass ends with, kept for [`Scene::adjacency`].
    adjacency_cache: Memo<adjacency::Adjacency>,
    /// The seals [`Scene::mark_sealed`] found, kept for [`Scene::seals`].
    seal_cache: Memo<seal::Seals>,
}

/// What was found from the polygons, kept with the fingerprint of the polygons it was found
/// for: used only while the polygons are still those (a scene's polygons are public, and
/// anyone may change them). Equal to every other memo: it is not part of what a scene is.
#[derive(Debug, Clone)]
struct Memo<T>(Option<(u64, std::sync::Arc<T>)>);

impl<T> Default for Memo<T> {
    fn default() -> Self {
        Memo(None)
    }
}

impl<T> PartialEq for Memo<T> {
    fn eq(&self, _: &Memo<T>) -> bool {
        true
    }
}

impl<T> Memo<T> {
    /// `value`, found for `polygons`.
    fn of(polygons: &[Polygon], value: T) -> Memo<T> {
        Memo(Some((
            geometry_fingerprint(polygons),
            std::sync::Arc::new(value),
        )))
    }

    /// The value kept if it was found for `polygons`, else `find` of them.
    fn get_or(&self, polygons: &[Polygon], find: impl FnOnce() -> T) -> std::sync::Arc<T> {
        match &self.0 {
            Some((f, a)) if *f == geometry_fingerprint(polygons) => std::sync::Arc::clone(a),
            _ => std::sync::Arc::new(find()),
        }
    }
}

/// A fingerprint of the polygons' geometry (every corner's bits and shape, in order): what
/// [`adjacency::Adjacency::of`] and [`seal::sealed`] depend on.
fn geometry_fingerprint(polygons: &[Polygon]) -> u64 {
    // FNV-1a over 64-bit words.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut word = |w: u64| {
        h ^= w;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    };
    word(polygons.len() as u64);
    for p in polygons {
        word(p.shape as u64);
        for c in &p.corners {
            for x in c.to_array() {
                word(x.to_bits());
            }
        }
    }
    h
}

/// A polygon more than this many times the diagonal of the rest of the scene is a backdrop
/// ([`Scene::core_diagonal`]): far beyond any room's largest wall (at most about its
/// diagonal), well below the ground planes and sky boxes that dwarf a model.
pub const BACKDROP_RATIO: f64 = 16.0;

/// Most polygons [`Scene::core_diagonal`] sets aside as backdrops (a sky box's six faces and
/// a ground plane, with room to spare).
pub const MAX_BACKDROPS: usize = 16;

impl Scene {
    /// A scene built in code (tests, benchmarks): the given camera, image size, materials and
    /// polygons, one object named "code", no spot lights, no source file, default settings.
    /// The caller keeps the invariants listed in the module docs.
    pub fn new(
        camera: Camera,
        width: u32,
        height: u32,
        materials: Vec<Material>,
        polygons: Vec<Polygon>,
    ) -> Scene {
        Scene {
            source: std::path::PathBuf::new(),
            camera,
            width,
            height,
            materials,
            objects: vec!["code".to_string()],
            polygons,
            spots: Vec::new(),
            spot_origins: Vec::new(),
            radiosity: RadiositySettings::default(),
            render: RenderSettings::default(),
            display: DisplaySettings::default(),
            camera_path: None,
            warnings: Vec::new(),
            notes: Vec::new(),
            inputs: Vec::new(),
            origins: Vec::new(),
            contacts: contact::Cuts::default(),
            merged: triangle_pairs::Merged::default(),
            junctions: contact::Cuts::default(),
            adjacency_cache: Memo::default(),
            seal_cache: Memo::default(),
        }
    }

    /// Cuts the polygons along their contact lines ([`contact`]), keeping `origins` aligned,
    /// and records what was cut in `contacts`. The loader does this for every scene whose
    /// `radiosity.cut_contacts` is on; a scene built in code does it when it asks.
    pub fn cut_contacts(&mut self) {
        let stacking = coincident::Stacking::of(&self.polygons, &self.materials);
        let lines = contact::find(&self.polygons, &stacking);
        self.contacts = contact::cut(&mut self.polygons, &mut self.origins, lines);
        // Each cut polygon's first piece: the polygons before it, less the pieces they lost
        // plus those they gained.
        let mut shift = 0i64;
        let mut places = Vec::with_capacity(self.contacts.pieces.len());
        for &(orig, n) in &self.contacts.pieces {
            places.push(self.origin((orig as i64 + shift) as usize));
            shift += n as i64 - 1;
        }
        self.contacts.places = places;
    }

    /// Cuts polygons through their T-junctions whose lattices do not line up ([`junctions`]),
    /// keeping `origins` aligned, and records what was cut in `junctions`. The loader does this
    /// for every scene, after the contact cuts (whose pieces may leave such T-junctions with
    /// their neighbours); a scene built in code does it when it asks.
    pub fn cut_t_junctions(&mut self) {
        let (cuts, adjacency) =
            junctions::cut(&mut self.polygons, &mut self.origins, &self.materials);
        self.junctions = cuts;
        self.adjacency_cache =
            adjacency.map_or_else(Memo::default, |a| Memo::of(&self.polygons, a));
    }

    /// Finds the sealed polygons and those backed by a face in their plane ([`seal::sealed`]),
    /// marks each one's [`Polygon::sealed`] and [`Polygon::backed`], and keeps them for
    /// [`Scene::seals`]. The loader does this for every scene after its cuts; a
    /// scene built in code does it when it asks.
    pub fn mark_sealed(&mut self) {
        let seals = seal::sealed(self);
        for (i, p) in self.polygons.iter_mut().enumerate() {
            p.sealed = seals.kind(i as u32);
            p.backed = seals.is_backed(i as u32);
        }
        self.seal_cache = Memo::of(&self.polygons, seals);
    }

    /// The sealed polygons ([`seal::sealed`]): those [`Scene::mark_sealed`] found while the
    /// polygons are still those it found them for, else found now.
    pub fn seals(&self) -> std::sync::Arc<seal::Seals> {
        self.seal_cache
            .get_or(&self.polygons, || seal::sealed(self))
    }

    /// The shared edges of the polygons ([`adjacency::Adjacency::of`]): the one the T-junction
    /// pass ended with when the polygons are still those it was found for (checked by a
    /// fingerprint of their geometry, far cheaper than finding it again), else found now.
    pub fn adjacency(&self) -> std::sync::Arc<adjacency::Adjacency> {
        self.adjacency_cache
            .get_or(&self.polygons, || adjacency::Adjacency::of(&self.polygons))
    }

    /// Where polygon `i` was written (`file:line: key`), or `polygon i` for a scene built in
    /// code.
    pub fn origin(&self, i: usize) -> String {
        self.origins
            .get(i)
            .map_or_else(|| format!("polygon {i}"), |l| l.to_string())
    }

    /// Where spot light `k` was written (`file:line: spots[k].position`, or the glTF light
    /// it came from); `spots[k].position` of the scene's file for a scene built in code.
    pub fn spot_location(&self, k: usize) -> base::error::Location {
        self.spot_origins.get(k).cloned().unwrap_or_else(|| {
            base::error::Location::file(&self.source).with_key(format!("spots[{k}].position"))
        })
    }

    /// The material of polygon `i`.
    pub fn material_of(&self, i: usize) -> &Material {
        &self.materials[self.polygons[i].material as usize]
    }

    /// Axis-aligned bounds of all polygon corners and spot light positions: (min, max).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for p in &self.polygons {
            for c in p.vertices() {
                lo = lo.min(*c);
                hi = hi.max(*c);
            }
        }
        self.bounds_with(lo, hi)
    }

    /// The diagonal of the scene's core: [`Scene::bounds`] without its backdrops, the largest
    /// polygons (at most [`MAX_BACKDROPS`]) each more than [`BACKDROP_RATIO`] times the
    /// diagonal of everything else (spot lights included). A ground plane 1e6 wide beside a
    /// room is not the room's scale: the lengths derived from the scene's size (the smallest
    /// element the solver refines to, its plane tolerance) come from the room, so adding such
    /// a polygon coarsens nothing else. 0 for a scene with no finite bound.
    pub fn core_diagonal(&self) -> f64 {
        use crate::bvh::Aabb;
        let n = self.polygons.len();
        let boxes: Vec<Aabb> = self
            .polygons
            .iter()
            .map(|p| Aabb::of(p.vertices()))
            .collect();
        let size = |b: Aabb| {
            if b.lo.is_finite() {
                (b.hi - b.lo).length()
            } else {
                0.0
            }
        };
        // Largest first; ties by index, so the result depends only on the scene.
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| size(boxes[b]).total_cmp(&size(boxes[a])).then(a.cmp(&b)));
        // suffix[k]: the bounds of polygons order[k..] and the spots.
        let spots = self
            .spots
            .iter()
            .fold(Aabb::EMPTY, |b, s| b.grow(s.position));
        let mut suffix = vec![spots; n + 1];
        for k in (0..n).rev() {
            suffix[k] = suffix[k + 1].union(boxes[order[k]]);
        }
        let backdrops = (1..=MAX_BACKDROPS.min(n.saturating_sub(1)))
            .filter(|&k| size(boxes[order[k - 1]]) > BACKDROP_RATIO * size(suffix[k]))
            .max()
            .unwrap_or(0);
        size(suffix[backdrops])
    }

    /// The segment parameter from which a ray cast as a segment some multiple of the scene's
    /// diagonal long counts hits ([`bvh::Bvh::first_hit_from`]): `T_EPS` times the core's
    /// diagonal ([`Scene::core_diagonal`]) over the whole diagonal, so that a ray's blind zone
    /// at its origin scales with the geometry around it, not with a backdrop a million times a
    /// room's size that sets the ray's length; `T_EPS` itself, to the bit, without backdrops.
    pub fn ray_t0(&self) -> f64 {
        let (lo, hi) = self.bounds();
        let diagonal = (hi - lo).length();
        let core = self.core_diagonal();
        if diagonal > 0.0 && diagonal.is_finite() && core > 0.0 && core < diagonal {
            bvh::T_EPS * (core / diagonal)
        } else {
            bvh::T_EPS
        }
    }

    /// [`Scene::bounds`] from the bounds (`lo`, `hi`) of the polygon corners, computed by the
    /// caller (the renderer's geometry stage does it in parallel): the spot lights added, and
    /// (0, 0) for a scene with no finite bound.
    pub fn bounds_with(&self, mut lo: DVec3, mut hi: DVec3) -> (DVec3, DVec3) {
        for s in &self.spots {
            lo = lo.min(s.position);
            hi = hi.max(s.position);
        }
        if !lo.is_finite() {
            return (DVec3::ZERO, DVec3::ZERO);
        }
        (lo, hi)
    }

    /// Number of polygons whose material emits.
    pub fn emitter_count(&self) -> usize {
        (0..self.polygons.len())
            .filter(|&i| self.material_of(i).is_emitter())
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A horizontal square of side `w` at height `y`, its lower corner at (`x`, `y`, `z`).
    fn square(x: f64, y: f64, z: f64, w: f64) -> Polygon {
        let c = |dx: f64, dz: f64| DVec3::new(x + dx, y, z + dz);
        Polygon::quad([c(0.0, 0.0), c(w, 0.0), c(w, -w), c(0.0, -w)], 0, 0).unwrap()
    }

    /// The adjacency kept from the T-junction pass is the polygons' own, and is not used once
    /// the polygons change.
    #[test]
    fn the_kept_adjacency_serves_only_the_polygons_it_was_found_for() {
        let q = |x0: f64, z0: f64, w: f64, h: f64| {
            let c = |x: f64, z: f64| DVec3::new(x, 0.0, -z);
            Polygon::quad(
                [c(x0, z0), c(x0 + w, z0), c(x0 + w, z0 + h), c(x0, z0 + h)],
                0,
                0,
            )
            .unwrap()
        };
        // A strip with a square on a third of its side: one T-junction cut.
        let mut s = scene_of(vec![q(0.0, 0.0, 3.0, 1.0), q(0.0, 1.0, 1.0, 1.0)]);
        s.cut_t_junctions();
        assert_eq!(s.polygons.len(), 3);
        assert!(s.adjacency_cache.0.is_some());
        assert_eq!(*s.adjacency(), adjacency::Adjacency::of(&s.polygons));
        s.polygons.pop();
        assert_eq!(*s.adjacency(), adjacency::Adjacency::of(&s.polygons));
        s.polygons[0].corners[1].x += 0.5;
        assert_eq!(*s.adjacency(), adjacency::Adjacency::of(&s.polygons));
    }

    fn scene_of(polygons: Vec<Polygon>) -> Scene {
        let camera = Camera {
            eye: DVec3::new(0.0, 1.0, 3.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            projection: Projection::Perspective { fov_y_deg: 60.0 },
        };
        let grey = Material {
            name: "grey".into(),
            reflectance: DVec3::splat(0.5),
            emission: DVec3::ZERO,
        };
        Scene::new(camera, 8, 8, vec![grey], polygons)
    }

    #[test]
    fn the_core_leaves_out_backdrops_only() {
        let floor = square(0.0, 0.0, 0.0, 1.0);
        let lamp = square(0.4, 1.0, -0.4, 0.2);
        let room = (DVec3::new(1.0, 1.0, 1.0)).length();
        let core = |ps: Vec<Polygon>| scene_of(ps).core_diagonal();
        assert!((core(vec![floor.clone(), lamp.clone()]) - room).abs() < 1e-12);
        // A ground plane, a wall beside, and both: the room's size stays.
        let ground = square(-1e6, -1.0, 1e6, 2e6);
        let beside = square(5.0, 0.5, 0.0, 1e6);
        for extra in [
            vec![ground.clone()],
            vec![beside.clone()],
            vec![ground, beside],
        ] {
            let mut ps = vec![floor.clone(), lamp.clone()];
            ps.extend(extra);
            assert!((core(ps) - room).abs() < 1e-12);
        }
        // A room's largest surface is not a backdrop (a floor 10 wide under the lamp and a
        // table: 14.1 is not 16 times the rest's 1.5), nor are two rooms far apart. Under a
        // lone lamp (0.28) the same floor is one; its own max_depth still bounds its leaves.
        let big_floor = square(-5.0, 0.0, 5.0, 10.0);
        let table = square(0.0, 0.5, 0.0, 1.0);
        let want = (DVec3::new(10.0, 1.0, 10.0)).length();
        let furnished = core(vec![big_floor.clone(), lamp.clone(), table]);
        assert!((furnished - want).abs() < 1e-9, "{furnished}");
        let lone = core(vec![big_floor, lamp.clone()]);
        assert!((lone - 0.08f64.sqrt()).abs() < 1e-9, "{lone}");
        let far = square(1e6, 0.0, 0.0, 1.0);
        let both = core(vec![floor.clone(), lamp, far]);
        assert!(both > 1e6, "{both}");
        // One polygon, or none: the bounds themselves.
        assert!((core(vec![floor]) - 2f64.sqrt()).abs() < 1e-12);
        assert_eq!(core(vec![]), 0.0);
    }

    #[test]
    fn unit_square_parametric_map() {
        let q = Polygon::quad(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(2.0, 0.0, 0.0),
                DVec3::new(2.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            0,
            0,
        )
        .unwrap();
        assert_eq!(q.normal, DVec3::Z);
        assert!((q.area - 2.0).abs() < 1e-15);
        assert_eq!(q.point(0.5, 0.5), DVec3::new(1.0, 0.5, 0.0));
        assert!((q.area_element(0.3, 0.7) - 2.0).abs() < 1e-15);
    }

    #[test]
    fn triangle_collapses_v1_edge_and_integrates_to_area() {
        let t = Polygon::triangle(
            [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            0,
            0,
        )
        .unwrap();
        assert!((t.area - 0.5).abs() < 1e-15);
        assert_eq!(t.point(0.3, 1.0), DVec3::new(0.0, 1.0, 0.0));
        // Area element is 2 * area * (1 - v): midpoint rule in v is exact for a linear integrand.
        let n = 64;
        let mut s = 0.0;
        for j in 0..n {
            let v = (j as f64 + 0.5) / n as f64;
            s += t.area_element(0.5, v) / n as f64;
        }
        assert!((s - 0.5).abs() < 1e-12);
    }

    #[test]
    fn degenerate_polygons_are_refused() {
        let z = DVec3::ZERO;
        assert!(Polygon::triangle([z, DVec3::X, 2.0 * DVec3::X], 0, 0).is_none());
        assert!(Polygon::triangle([z, DVec3::X, DVec3::new(f64::NAN, 0.0, 0.0)], 0, 0).is_none());
    }

    #[test]
    fn spot_cone_and_falloff() {
        let s = SpotLight {
            position: DVec3::ZERO,
            direction: -DVec3::Z,
            intensity: DVec3::splat(2.0),
            half_angle: 30f64.to_radians(),
            falloff: 2.0,
        };
        assert_eq!(s.intensity_towards(-DVec3::Z), DVec3::splat(2.0));
        let w = DVec3::new(20f64.to_radians().sin(), 0.0, -20f64.to_radians().cos());
        let expect = 2.0 * 20f64.to_radians().cos().powi(2);
        assert!((s.intensity_towards(w).x - expect).abs() < 1e-14);
        let w = DVec3::new(40f64.to_radians().sin(), 0.0, -40f64.to_radians().cos());
        assert_eq!(s.intensity_towards(w), DVec3::ZERO);
    }
}
