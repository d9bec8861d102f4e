//! Fig. 5 and Fig. 6 of the paper, and the spot sweep: the two-spots plane in texture space,
//! the oracle reference, the coarse quadtree and its reconstructions (bilinear, bicubic RRP,
//! small textures with on-screen filters, the direct method), each measured against the reference.

use base::error::{Error, Location, Result};
use base::method::{Method, Placement};
use base::quadtree::{Quadtree, SampledQuadtree};
use engine::frame::{self, Frame, FrameOptions};
use engine::shading::Shader;
use glam::Vec3;
use metric::{compare, Comparison, LinearImage};
use radiosity::{self, Oracle, SolveOptions};
use reconstruction::texture::{Filter, RadiosityTexture, TextureMemory, TextureSet, GUTTER};
use reconstruction::{Estimator, Reconstruction};
use scene::{load_scene, Scene};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The paper's Fig. 5 distances to its reference: bicubic, bilinear.
pub const PAPER_FIG5: (f64, f64) = (65.03, 69.67);
/// The paper's Fig. 6 distances to its reference: hardware bicubic, hardware bilinear.
pub const PAPER_FIG6: (f64, f64) = (167.3, 218.3);

/// What the figure experiments are run with.
#[derive(Debug, Clone)]
pub struct FigureOptions {
    /// The two-spots scene (a unit square seen orthographically).
    pub scene: PathBuf,
    /// Side of the images (the paper: 256).
    pub size: u32,
    /// Depth of the paper's full-sampling reference (the paper: 9, 513 x 513 samples).
    pub reference_depth: u32,
    /// Depth of the coarse quadtree that is reconstructed (the paper: 2, 5 x 5 samples).
    pub coarse_depth: u32,
    /// Side of the Fig. 6 texture (the paper: 8).
    pub texture_size: u32,
    /// Pixels per degree of the perceptual metric.
    pub ppd: f64,
    /// How the RRPs estimate vertex derivatives (default: [`Estimator::default`]).
    pub estimator: Estimator,
    /// Replaces the first spot light's falloff exponent (the spot sweep), widening its cone to
    /// [`sweep_half_angle`] so that only the spot's width changes; `None` keeps the scene's.
    pub first_spot_falloff: Option<f64>,
    /// Moves the first spot light by this much along x and y (scene units; the sensitivity to
    /// where the spot's peak falls between the coarse grid's samples).
    pub first_spot_shift: [f64; 2],
    /// Where images are written (`None`: nothing is written).
    pub out_dir: Option<PathBuf>,
    /// The registry images are written through (atomically, removable on interrupt).
    pub outputs: base::output::Outputs,
    /// The instruction set the frames run with (the images do not depend on it).
    pub isa: lanes::Isa,
}

impl FigureOptions {
    /// The paper's settings on `scene`, writing nothing.
    pub fn paper(scene: &Path) -> FigureOptions {
        FigureOptions {
            scene: scene.to_path_buf(),
            size: 256,
            reference_depth: 9,
            coarse_depth: 2,
            texture_size: 8,
            ppd: metric::DEFAULT_PPD,
            estimator: Estimator::default(),
            first_spot_falloff: None,
            first_spot_shift: [0.0, 0.0],
            out_dir: None,
            outputs: base::output::Outputs::new(),
            isa: lanes::Isa::detect(),
        }
    }
}

/// One image of a figure and its distance to the oracle reference.
#[derive(Debug, Clone, Serialize)]
pub struct Panel {
    /// The paper's panel letter and what it shows, e.g. `(d) bicubic RRP resampled to 256 x 256`.
    pub label: String,
    /// Short key (`bicubic`, `bilinear`, `direct`, ...).
    pub key: String,
    /// The PNG written, relative to the output directory (empty if nothing was written).
    pub file: String,
    /// Every measure against the oracle reference (`None` for the reference itself).
    pub versus_reference: Option<Comparison>,
    /// The linear image.
    #[serde(skip)]
    pub image: LinearImage,
}

/// A figure: its panels and the paper's numbers for the two that it reported.
#[derive(Debug, Clone, Serialize)]
pub struct Figure {
    /// `fig5` or `fig6`.
    pub name: String,
    /// Panels in the paper's order, the oracle reference first.
    pub panels: Vec<Panel>,
    /// The paper's (bicubic, bilinear) distances.
    pub paper: (f64, f64),
    /// Pixels per degree used.
    pub ppd: f64,
}

impl Figure {
    /// The panel with key `key`.
    pub fn panel(&self, key: &str) -> Option<&Panel> {
        self.panels.iter().find(|p| p.key == key)
    }

    /// Perceptual distance of panel `key` to the reference (0 for the reference itself).
    pub fn distance(&self, key: &str) -> Option<f64> {
        self.panel(key).map(|p| {
            p.versus_reference
                .as_ref()
                .map_or(0.0, |c| c.perceptual_distance)
        })
    }
}

/// Where a spot's cone may cut off once the light has fallen to this fraction of the axis
/// intensity: the cut is then invisible.
pub const CONE_EDGE_FRACTION: f64 = 1e-6;

/// The widest half-angle the sweep gives a spot: just below 90 degrees (a cone of 90 degrees
/// or more would light the plane's back side, and the scene format stops at 90).
pub const MAX_SWEEP_HALF_ANGLE_DEG: f64 = 89.0;

/// The half-angle (radians) the spot sweep gives a spot of falloff `falloff` whose scene half
/// angle is `scene_half` (radians): the angle where cos^falloff falls to
/// [`CONE_EDGE_FRACTION`], capped at [`MAX_SWEEP_HALF_ANGLE_DEG`], and never narrower than
/// the scene's. Lowering the falloff without widening the cone would let the cone's edge cut
/// the spot (cos^8 of 40 degrees is 12 % of the peak), changing its shape, not just its width.
pub fn sweep_half_angle(falloff: f64, scene_half: f64) -> f64 {
    let cap = MAX_SWEEP_HALF_ANGLE_DEG.to_radians();
    let edge = if falloff > 0.0 {
        CONE_EDGE_FRACTION.powf(1.0 / falloff).acos().min(cap)
    } else {
        cap
    };
    edge.max(scene_half)
}

/// The two-spots data both figures start from.
struct Setup {
    scene: Scene,
    solution: radiosity::Solution,
}

impl Setup {
    fn new(path: &Path, falloff: Option<f64>, shift: [f64; 2]) -> Result<Setup> {
        let mut scene = load_scene(path)?;
        if shift != [0.0, 0.0] {
            let spot = scene
                .spots
                .first_mut()
                .ok_or_else(|| Error::input(Location::file(path), "no spot light to move"))?;
            spot.position.x += shift[0];
            spot.position.y += shift[1];
        }
        if let Some(f) = falloff {
            let spot = scene
                .spots
                .first_mut()
                .ok_or_else(|| Error::input(Location::file(path), "no spot light to vary"))?;
            if !(f.is_finite() && f >= 0.0) {
                return Err(Error::invalid_option(
                    "spot falloff",
                    f.to_string(),
                    "must be >= 0",
                ));
            }
            spot.falloff = f;
            spot.half_angle = sweep_half_angle(f, spot.half_angle);
        }
        if scene.polygons.len() != 1 {
            return Err(Error::input(
                Location::file(path),
                format!(
                    "the figure experiments need a single-polygon texture-space scene \
                     (scenes/two-spots.toml), this one has {} polygons",
                    scene.polygons.len()
                ),
            ));
        }
        let solution = radiosity::solve(&scene, &SolveOptions::default())?;
        Ok(Setup { scene, solution })
    }

    fn oracle(&self) -> Result<Oracle<'_>> {
        Oracle::new(&self.solution, &self.scene)
    }
}

/// A quadtree split uniformly to `depth`.
fn full_tree(depth: u32) -> Quadtree {
    let mut t = Quadtree::new();
    let mut frontier = vec![0u32];
    for _ in 0..depth {
        let mut next = Vec::with_capacity(frontier.len() * 4);
        for n in frontier {
            let first = t.split(n);
            next.extend(first..first + 4);
        }
        frontier = next;
    }
    t
}

/// The oracle sampled at every vertex of the full depth-`depth` quadtree of polygon 0.
fn sampled(oracle: &Oracle<'_>, depth: u32) -> SampledQuadtree {
    SampledQuadtree::from_fn(full_tree(depth), |u, v| oracle.radiosity(0, u, v))
}

/// The (u, v) of the centre of pixel (x, y) of an n x n texture-space image.
fn pixel_uv(x: u32, y: u32, n: u32) -> (f64, f64) {
    (
        (x as f64 + 0.5) / n as f64,
        1.0 - (y as f64 + 0.5) / n as f64,
    )
}

/// Bilinear interpolation of a full grid of (2^depth + 1)^2 samples at (u, v) in [0, 1]^2.
fn grid_bilinear(samples: &SampledQuadtree, depth: u32, u: f64, v: f64) -> Vec3 {
    let n = 1u32 << depth;
    let (x, y) = (u * n as f64, v * n as f64);
    let (i, j) = ((x.floor() as u32).min(n - 1), (y.floor() as u32).min(n - 1));
    let (s, t) = ((x - i as f64) as f32, (y - j as f64) as f32);
    let step = base::quadtree::LATTICE >> depth;
    let at = |a: u32, b: u32| {
        samples
            .sample(base::quadtree::VertexKey::new(a * step, b * step))
            .unwrap_or(Vec3::ZERO)
    };
    let lo = at(i, j) * (1.0 - s) + at(i + 1, j) * s;
    let hi = at(i, j + 1) * (1.0 - s) + at(i + 1, j + 1) * s;
    lo * (1.0 - t) + hi * t
}

/// The nearest of a full grid's samples at (u, v): how panel (b) shows the raw coarse data.
fn grid_nearest(samples: &SampledQuadtree, depth: u32, u: f64, v: f64) -> Vec3 {
    let n = 1u32 << depth;
    let (i, j) = ((u * n as f64).round() as u32, (v * n as f64).round() as u32);
    let step = base::quadtree::LATTICE >> depth;
    samples
        .sample(base::quadtree::VertexKey::new(
            i.min(n) * step,
            j.min(n) * step,
        ))
        .unwrap_or(Vec3::ZERO)
}

fn image_of(n: u32, f: impl Fn(f64, f64) -> Vec3) -> LinearImage {
    LinearImage::from_fn(n, n, |x, y| {
        let (u, v) = pixel_uv(x, y, n);
        f(u, v)
    })
}

fn image_of_frame(frame: Frame) -> Result<LinearImage> {
    LinearImage::new(frame.width, frame.height, frame.pixels)
}

/// The frame options of a figure's `size` x `size` images.
fn frame_options(opts: &FigureOptions) -> FrameOptions {
    FrameOptions {
        isa: opts.isa,
        ..FrameOptions::new(opts.size, opts.size)
    }
}

/// Makes the panels of one figure: writes each image (when the options name a directory) and
/// measures it against the oracle reference.
struct Panels<'a> {
    opts: &'a FigureOptions,
    scene: &'a Scene,
    /// `fig5` or `fig6`, the start of the images' file names.
    fig: &'a str,
    /// The oracle reference image.
    reference: &'a LinearImage,
}

impl Panels<'_> {
    /// Panel (a): the oracle reference itself.
    fn reference(&self) -> Result<Panel> {
        self.panel(
            "reference",
            "(a) reference: the solver's oracle at every pixel",
            self.reference.clone(),
            None,
        )
    }

    /// A panel measured against the reference.
    fn measured(&self, key: &str, label: &str, image: LinearImage) -> Result<Panel> {
        self.panel(key, label, image, Some(self.reference))
    }

    /// Panel `key`, written when asked, measured against `reference` when given.
    fn panel(
        &self,
        key: &str,
        label: &str,
        image: LinearImage,
        reference: Option<&LinearImage>,
    ) -> Result<Panel> {
        let versus_reference = match reference {
            Some(r) => Some(compare(&image, r, self.opts.ppd)?),
            None => None,
        };
        let mut file = String::new();
        if let Some(dir) = &self.opts.out_dir {
            file = format!("{}-{key}.png", self.fig);
            imageio::write_png(
                &self.opts.outputs,
                &dir.join(&file),
                image.view(),
                self.scene.display.exposure,
            )?;
        }
        Ok(Panel {
            label: label.into(),
            key: key.into(),
            file,
            versus_reference,
            image,
        })
    }
}

fn check(opts: &FigureOptions) -> Result<()> {
    if opts.size == 0 || opts.size > 4096 {
        return Err(Error::invalid_option(
            "size",
            opts.size.to_string(),
            "must be in 1..=4096",
        ));
    }
    if opts.reference_depth > 12 || opts.coarse_depth > opts.reference_depth {
        return Err(Error::invalid_option(
            "reference depth",
            opts.reference_depth.to_string(),
            format!(
                "must be at most 12 and at least the coarse depth {}",
                opts.coarse_depth
            ),
        ));
    }
    if let Some(dir) = &opts.out_dir {
        std::fs::create_dir_all(dir).map_err(|e| Error::Io {
            path: dir.clone(),
            error: e,
        })?;
    }
    Ok(())
}

/// The oracle reference image: the exact radiosity at every pixel centre, rendered by the
/// `reference` backend (the rasterizer's (u, v), the solver's oracle).
fn oracle_image(
    setup: &Setup,
    oracle: &Oracle<'_>,
    n: u32,
    isa: lanes::Isa,
) -> Result<LinearImage> {
    let f = |p: u32, u: f32, v: f32| oracle.radiosity(p as usize, u as f64, v as f64);
    let frame = frame::render(
        &setup.scene,
        &setup.scene.camera,
        &Shader::Reference(&f),
        Method::Reference,
        &FrameOptions {
            isa,
            ..FrameOptions::new(n, n)
        },
    )?;
    image_of_frame(frame)
}

/// Fig. 5: reconstruction of a coarse (depth-2) quadtree in texture space, bilinear against
/// bicubic (RRP) resampling, and the direct method, against the reference.
pub fn fig5(opts: &FigureOptions) -> Result<Figure> {
    check(opts)?;
    let setup = Setup::new(&opts.scene, opts.first_spot_falloff, opts.first_spot_shift)?;
    let oracle = setup.oracle()?;
    let n = opts.size;
    let scene = &setup.scene;
    let reference = oracle_image(&setup, &oracle, n, opts.isa)?;
    let (rd, cd) = (opts.reference_depth, opts.coarse_depth);
    let fine = sampled(&oracle, rd);
    let coarse = sampled(&oracle, cd);
    let recon = Reconstruction::build(std::slice::from_ref(&coarse), opts.estimator)?;
    let texels = recon.resample(0, n, n);
    // Texel row j holds v = (j + 0.5) / n; image row y shows v = 1 - (y + 0.5) / n: row n-1-y.
    let bicubic = LinearImage::from_fn(n, n, |x, y| texels[((n - 1 - y) * n + x) as usize]);
    let direct = image_of_frame(frame::render_patches(
        scene,
        &scene.camera,
        &recon,
        &frame_options(opts),
    )?)?;
    let side = (1u32 << cd) + 1;
    let p = Panels {
        opts,
        scene,
        fig: "fig5",
        reference: &reference,
    };
    let panels = vec![
        p.reference()?,
        p.measured(
            "full",
            &format!(
                "(a') the paper's reference: depth-{rd} quadtree ({0} x {0} samples), bilinear",
                (1u32 << rd) + 1
            ),
            image_of(n, |u, v| grid_bilinear(&fine, rd, u, v)),
        )?,
        p.measured(
            "coarse",
            &format!("(b) depth-{cd} quadtree ({side} x {side} samples), nearest sample"),
            image_of(n, |u, v| grid_nearest(&coarse, cd, u, v)),
        )?,
        p.measured(
            "bilinear",
            &format!("(c) RAT: bilinear resampling of (b) to {n} x {n}"),
            image_of(n, |u, v| grid_bilinear(&coarse, cd, u, v)),
        )?,
        p.measured(
            "bicubic",
            &format!("(d) RAT: bicubic (RRP) resampling of (b) to {n} x {n}"),
            bicubic,
        )?,
        p.measured(
            "direct",
            &format!("(e) direct: the RRPs of (b) evaluated per pixel at {n} x {n}"),
            direct,
        )?,
    ];
    Ok(Figure {
        name: "fig5".into(),
        panels,
        paper: PAPER_FIG5,
        ppd: opts.ppd,
    })
}

/// Fig. 6: the bicubic RRP of the coarse quadtree resampled to a small texture and drawn with
/// bilinear and with bicubic (Mitchell–Netravali) on-screen filtering, and the direct method;
/// then the same two filters on a texture of the same size resampled at corner-aligned texels
/// ([`Placement::Corner`], panels `corner-bilinear` and `corner-bicubic`), and on the
/// centre-texel texture without its gutter, so that a filter reaching past the last texel reads
/// the edge texel again (clamp to edge, the addressing of the paper's RealityEngine textures:
/// panels `clamp-bilinear` and `clamp-bicubic`).
pub fn fig6(opts: &FigureOptions) -> Result<Figure> {
    check(opts)?;
    let setup = Setup::new(&opts.scene, opts.first_spot_falloff, opts.first_spot_shift)?;
    let oracle = setup.oracle()?;
    let reference = oracle_image(&setup, &oracle, opts.size, opts.isa)?;
    let coarse = sampled(&oracle, opts.coarse_depth);
    let recon = Reconstruction::build(std::slice::from_ref(&coarse), opts.estimator)?;
    TextureSet::sizes(
        &[Default::default()],
        reconstruction::texture::SizePolicy::Fixed(opts.texture_size),
    )?;
    let fig = SmallTexture {
        opts,
        scene: &setup.scene,
        recon: &recon,
        fopts: frame_options(opts),
    };
    let panels = fig.panels(&Panels {
        opts,
        scene: &setup.scene,
        fig: "fig6",
        reference: &reference,
    })?;
    Ok(Figure {
        name: "fig6".into(),
        panels,
        paper: PAPER_FIG6,
        ppd: opts.ppd,
    })
}

/// Fig. 6's drawing: the coarse data's RRP resampled to one `texture_size` x `texture_size`
/// texture and drawn on screen with a filter, beside the RRP drawn directly.
struct SmallTexture<'a> {
    opts: &'a FigureOptions,
    scene: &'a Scene,
    /// The RRP of the coarse quadtree.
    recon: &'a Reconstruction,
    /// The figure's frame options.
    fopts: FrameOptions,
}

impl SmallTexture<'_> {
    /// The RRP resampled to the texture, its texels at `placement`, with `gutter` texels of
    /// the RRP's continuation around it (0: none, so fetches past the edge clamp to it).
    fn texture(&self, placement: Placement, gutter: u32) -> TextureSet {
        let ts = self.opts.texture_size;
        TextureSet {
            memory: TextureMemory::of_sides(&[ts], gutter),
            textures: vec![RadiosityTexture::from_rrp(
                self.recon,
                0,
                (ts, ts),
                placement,
                gutter,
            )],
            placement,
            gutter,
        }
    }

    /// `set` drawn with `filter`.
    fn draw(&self, set: &TextureSet, filter: Filter) -> Result<LinearImage> {
        image_of_frame(frame::render(
            self.scene,
            &self.scene.camera,
            &Shader::Texture {
                set,
                filter,
                anisotropy: 1,
            },
            Method::Texture(filter),
            &self.fopts,
        )?)
    }

    /// The RRP evaluated per pixel: the direct method, no texture.
    fn direct(&self) -> Result<LinearImage> {
        image_of_frame(frame::render_patches(
            self.scene,
            &self.scene.camera,
            self.recon,
            &self.fopts,
        )?)
    }

    /// The panels in the paper's order, then the corner-aligned and the clamped ones.
    fn panels(&self, p: &Panels<'_>) -> Result<Vec<Panel>> {
        let (n, ts) = (self.opts.size, self.opts.texture_size);
        let (set, corner, clamped) = (
            self.texture(Placement::Centre, GUTTER),
            self.texture(Placement::Corner, GUTTER),
            self.texture(Placement::Centre, 0),
        );
        let direct = self.direct()?;
        Ok(vec![
            p.reference()?,
            p.measured(
                "texture",
                &format!("(b) the bicubic RRP resampled to {ts} x {ts} texels, shown nearest"),
                self.draw(&set, Filter::Nearest)?,
            )?,
            p.measured(
                "bilinear",
                &format!("(c) the {ts} x {ts} texture drawn at {n} x {n}, bilinear filtering"),
                self.draw(&set, Filter::Bilinear)?,
            )?,
            p.measured(
                "bicubic",
                &format!(
                    "(d) the {ts} x {ts} texture drawn at {n} x {n}, Mitchell-Netravali (1/3, 1/3)"
                ),
                self.draw(&set, Filter::MITCHELL)?,
            )?,
            p.measured(
                "direct",
                &format!("(e) direct: the RRPs evaluated per pixel at {n} x {n}"),
                direct,
            )?,
            p.measured(
                "corner-bilinear",
                &format!(
                    "(f) corner-aligned texels: the RRP at u = i / {}, {ts} x {ts}, bilinear",
                    ts.saturating_sub(1).max(1)
                ),
                self.draw(&corner, Filter::Bilinear)?,
            )?,
            p.measured(
                "corner-bicubic",
                &format!("(g) corner-aligned texels, {ts} x {ts}, Mitchell-Netravali (1/3, 1/3)"),
                self.draw(&corner, Filter::MITCHELL)?,
            )?,
            p.measured(
                "clamp-bilinear",
                &format!(
                    "(h) clamp to edge, as the paper's hardware addressed textures (no gutter): \
                     centre texels, {ts} x {ts}, bilinear"
                ),
                self.draw(&clamped, Filter::Bilinear)?,
            )?,
            p.measured(
                "clamp-bicubic",
                &format!(
                    "(i) clamp to edge, centre texels, {ts} x {ts}, Mitchell-Netravali (1/3, 1/3)"
                ),
                self.draw(&clamped, Filter::MITCHELL)?,
            )?,
        ])
    }
}

/// One falloff of the spot sweep: how well the coarse grid resolves the bright spot decides
/// which reconstruction wins.
#[derive(Debug, Clone, Serialize)]
pub struct SweepRow {
    /// The first spot's falloff exponent (cos^falloff inside the cone).
    pub falloff: f64,
    /// Radius on the plane where the spot's radiosity falls to 10 % of its peak, in units of the
    /// coarse grid's sample spacing: below about 1 the spot lies between samples.
    pub radius_in_spacings: f64,
    /// Fig. 5 distances: bilinear, bicubic, direct.
    pub fig5: (f64, f64, f64),
    /// What the peak sample's four grid neighbours (one spacing away) hold, as a fraction of the
    /// peak ([`spot_fraction_at`]; the first spot alone).
    pub neighbour_fraction: f64,
    /// The first spot's half-angle in the sweep, degrees ([`sweep_half_angle`]).
    pub half_angle_deg: f64,
    /// Fig. 6 distances with texels at their centres: bilinear, bicubic (Mitchell), direct.
    pub fig6: (f64, f64, f64),
    /// Fig. 6 distances with corner-aligned texels: bilinear, bicubic (Mitchell).
    pub fig6_corner: (f64, f64),
    /// Fig. 6 distances with centre texels clamped to the edge (no gutter, the paper's
    /// hardware): bilinear, bicubic (Mitchell).
    pub fig6_clamp: (f64, f64),
    /// How far the four distances the paper reports (Fig. 5 and Fig. 6 centre texels, bicubic
    /// and bilinear) are from the paper's up to one common scale ([`paper_misfit`]).
    pub misfit: f64,
    /// The same with Fig. 6 drawn as the paper's hardware drew it (clamp to edge).
    pub misfit_clamp: f64,
}

impl SweepRow {
    /// Whether the direct method is the closest to the reference in both figures: below every
    /// texture of Fig. 6 (both placements, and clamped to the edge), and in Fig. 5 within 1e-4 of the better of bilinear
    /// and bicubic (it evaluates the same RRPs as the bicubic panel there).
    pub fn direct_closest(&self) -> bool {
        let textures6 = self
            .fig6
            .0
            .min(self.fig6.1)
            .min(self.fig6_corner.0)
            .min(self.fig6_corner.1)
            .min(self.fig6_clamp.0)
            .min(self.fig6_clamp.1);
        self.fig6.2 < textures6 && self.fig5.2 <= self.fig5.0.min(self.fig5.1) * (1.0 + 1e-4)
    }
}

/// The distance of four perceptual distances from the paper's four ([`PAPER_FIG5`],
/// [`PAPER_FIG6`], each (bicubic, bilinear)) up to one common scale: with
/// r_i = ln(ours_i / paper_i) and m their mean, the root mean square of r_i - m. 0 when ours
/// are the paper's times one factor; 0.1 when they scatter about 10 % around that. The metric's
/// scale is not the paper's (a different observer model and display), so only the shape of
/// the four (the two ratios and Fig. 6 against Fig. 5) can match. Arguments are (bilinear,
/// bicubic) pairs, as [`SweepRow`] holds them; NaN if any distance is not positive.
pub fn paper_misfit(fig5: (f64, f64), fig6: (f64, f64)) -> f64 {
    let ours = [fig5.1, fig5.0, fig6.1, fig6.0];
    let paper = [PAPER_FIG5.0, PAPER_FIG5.1, PAPER_FIG6.0, PAPER_FIG6.1];
    if ours.iter().any(|&x| x.is_nan() || x <= 0.0) {
        return f64::NAN;
    }
    let r: Vec<f64> = ours.iter().zip(paper).map(|(o, p)| (o / p).ln()).collect();
    let m = r.iter().sum::<f64>() / 4.0;
    (r.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / 4.0).sqrt()
}

/// The 10 % radius of a spot of falloff `n` at height `h` over a plane facing it, with
/// B proportional to cos^n(theta) cos(theta) / r^2 = cos^(n+3)(theta) / h^2 on the plane.
pub fn spot_radius_10(n: f64, h: f64) -> f64 {
    let theta = 0.1f64.powf(1.0 / (n + 3.0)).acos();
    h * theta.tan()
}

/// The fraction of its peak that a spot of falloff `n` at height `h`, pointing straight down at
/// a plane, leaves on the plane at distance `d` from the peak: B is proportional to
/// cos^(n+3)(theta) with cos(theta) = h / sqrt(h^2 + d^2). With `d` the coarse grid's spacing it
/// is what the peak's four grid neighbours hold (the criterion of `scenes/two-spots.toml`).
pub fn spot_fraction_at(n: f64, h: f64, d: f64) -> f64 {
    (h / (h * h + d * d).sqrt()).powf(n + 3.0)
}

/// Fig. 5 and Fig. 6 distances for each falloff of the first spot (images not written).
pub fn spot_sweep(opts: &FigureOptions, falloffs: &[f64]) -> Result<Vec<SweepRow>> {
    falloffs
        .iter()
        .map(|&f| {
            sweep_row(&FigureOptions {
                first_spot_falloff: Some(f),
                ..opts.clone()
            })
        })
        .collect()
}

/// Fig. 5 and Fig. 6 distances of one setting (images not written), with the first spot's
/// width in the coarse grid's terms.
pub fn sweep_row(opts: &FigureOptions) -> Result<SweepRow> {
    let scene = load_scene(&opts.scene)?;
    let spot = scene
        .spots
        .first()
        .ok_or_else(|| Error::input(Location::file(&opts.scene), "no spot light"))?;
    let h = spot.position.z.abs();
    let f = opts.first_spot_falloff.unwrap_or(spot.falloff);
    let half_angle = match opts.first_spot_falloff {
        Some(f) => sweep_half_angle(f, spot.half_angle),
        None => spot.half_angle,
    };
    let spacing = 1.0 / (1u32 << opts.coarse_depth) as f64;
    let o = FigureOptions {
        out_dir: None,
        ..opts.clone()
    };
    let (a, b) = (fig5(&o)?, fig6(&o)?);
    let d = |fig: &Figure| {
        (
            fig.distance("bilinear").unwrap_or(f64::NAN),
            fig.distance("bicubic").unwrap_or(f64::NAN),
            fig.distance("direct").unwrap_or(f64::NAN),
        )
    };
    let corner = (
        b.distance("corner-bilinear").unwrap_or(f64::NAN),
        b.distance("corner-bicubic").unwrap_or(f64::NAN),
    );
    let clamp = (
        b.distance("clamp-bilinear").unwrap_or(f64::NAN),
        b.distance("clamp-bicubic").unwrap_or(f64::NAN),
    );
    let (f5, f6) = (d(&a), d(&b));
    Ok(SweepRow {
        falloff: f,
        radius_in_spacings: spot_radius_10(f, h) / spacing,
        neighbour_fraction: spot_fraction_at(f, h, spacing),
        half_angle_deg: half_angle.to_degrees(),
        fig5: f5,
        fig6: f6,
        fig6_corner: corner,
        fig6_clamp: clamp,
        misfit: paper_misfit((f5.0, f5.1), (f6.0, f6.1)),
        misfit_clamp: paper_misfit((f5.0, f5.1), clamp),
    })
}

/// One row of the figures' sensitivity to a setting other than the spot's width.
#[derive(Debug, Clone, Serialize)]
pub struct Sensitivity {
    /// What was varied: `scene` (a shipped variant), `spot shift` (the first spot moved along
    /// x and y, in coarse sample spacings) or `pixels per degree` (the metric's viewing
    /// distance).
    pub parameter: String,
    /// Its value, as text (a scene path, a shift, a pixels-per-degree value).
    pub value: String,
    /// The figures' distances there.
    pub row: SweepRow,
}

/// The figures' distances on the shipped variants of the figure scene (the `.toml` files
/// beside it named in `variants` that exist), with the first spot moved by 1/4 and 1/2 of the
/// coarse spacing diagonally, and at half and twice the metric's pixels per degree (the viewer
/// twice as near or as far).
pub fn sensitivity(opts: &FigureOptions, variants: &[&str]) -> Result<Vec<Sensitivity>> {
    let mut rows = Vec::new();
    let dir = opts.scene.parent().unwrap_or(Path::new("."));
    for v in variants {
        let path = dir.join(v);
        if path.exists() && path != opts.scene {
            let row = sweep_row(&FigureOptions {
                scene: path,
                ..opts.clone()
            })?;
            rows.push(Sensitivity {
                parameter: "scene".into(),
                value: v.to_string(),
                row,
            });
        }
    }
    let spacing = 1.0 / (1u32 << opts.coarse_depth) as f64;
    for k in [0.25, 0.5] {
        let row = sweep_row(&FigureOptions {
            first_spot_shift: [k * spacing, -k * spacing],
            ..opts.clone()
        })?;
        rows.push(Sensitivity {
            parameter: "spot shift".into(),
            value: format!("({k}, -{k}) spacings"),
            row,
        });
    }
    for m in [0.5, 2.0] {
        let ppd = opts.ppd * m;
        let row = sweep_row(&FigureOptions {
            ppd,
            ..opts.clone()
        })?;
        rows.push(Sensitivity {
            parameter: "pixels per degree".into(),
            value: format!("{ppd}"),
            row,
        });
    }
    Ok(rows)
}

/// A figure's table in the paper's layout (distances to the reference in a row, the paper's
/// numbers beneath), then every measure per panel.
pub fn figure_text(f: &Figure) -> String {
    let (pb, pl) = f.paper;
    let d = |k: &str| f.distance(k).map_or("-".into(), |x| format!("{x:.4}"));
    let mut t = format!(
        "{}: perceptual distance to the reference (docs/metrics.md, {} pixels per degree)\n",
        f.name, f.ppd
    );
    t += "                 reference    bicubic   bilinear     direct\n";
    t += &format!(
        "reference (ours) {:>9} {:>10} {:>10} {:>10}\n",
        "0",
        d("bicubic"),
        d("bilinear"),
        d("direct")
    );
    t += &format!(
        "reference (paper){:>9} {:>10} {:>10} {:>10}\n",
        "0.0",
        format!("{pb:.2}"),
        format!("{pl:.2}"),
        "-"
    );
    if let (Some(b), Some(l)) = (f.distance("corner-bicubic"), f.distance("corner-bilinear")) {
        t += &format!(
            "corner texels    {:>9} {:>10} {:>10} {:>10}\n",
            "-",
            format!("{b:.4}"),
            format!("{l:.4}"),
            "-"
        );
    }
    if let (Some(b), Some(l)) = (f.distance("bicubic"), f.distance("bilinear")) {
        if l > 0.0 {
            t += &format!(
                "ratio bicubic/bilinear: ours {:.3}, paper {:.3}\n",
                b / l,
                pb / pl
            );
        }
    }
    t += "\npanel            perceptual      RMSE    max abs   rel. lum.  Mach band\n";
    for p in &f.panels {
        if let Some(c) = &p.versus_reference {
            t += &format!(
                "{:<15} {:>11.4} {:>9.5} {:>10.5} {:>11.5} {:>10.3e}\n",
                p.key,
                c.perceptual_distance,
                c.rmse,
                c.max_abs_error,
                c.relative_luminance_error,
                c.mach_band
            );
        }
    }
    for p in &f.panels {
        t += &format!("  {:<15} {}\n", p.key, p.label);
    }
    t
}
