//! Methods: the ways of drawing a radiosity solution, named once for the whole tool, and the
//! limits of their parameters.
//!
//! A [`Method`] is chosen by the scene file (`[render] method`) or the command line, so the scene
//! loader must be able to parse and check it before anything is solved: that is why this module
//! sits below every stage and depends on nothing but the error type. The stages that *implement*
//! a method (the texture filters, the patch shader, the mesh) live further down the frame
//! pipeline and take the plain values defined here ([`Filter`], the texture side limits, the
//! antialiasing sample counts, the texel [`Placement`]).
//!
//! Invariants: [`Method::parse`] and [`Method::name`] are inverse on [`Method::NAMES`]; every
//! constructor of a [`Filter::Bicubic`] through this module has B and C finite and in [0, 1].

use crate::error::{Error, Result};

/// Antialiasing sample counts per pixel the rasterizer has patterns for.
pub const AA_SAMPLE_COUNTS: [u32; 3] = [1, 4, 16];

/// Largest texture side of the texture methods (texels per axis).
pub const MAX_TEXTURE_SIZE: u32 = 4096;

/// On-screen reconstruction filter of the texture methods.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Filter {
    /// The texel containing the point (no blending).
    Nearest,
    /// 2 x 2 bilinear between the surrounding texel centres.
    Bilinear,
    /// Separable 4 x 4 Mitchell–Netravali cubic with parameters (B, C).
    Bicubic {
        /// B parameter.
        b: f32,
        /// C parameter.
        c: f32,
    },
}

impl Filter {
    /// Mitchell–Netravali with B = C = 1/3, the paper's filter and the default bicubic.
    pub const MITCHELL: Filter = Filter::Bicubic {
        b: 1.0 / 3.0,
        c: 1.0 / 3.0,
    };
    /// Catmull-Rom, B = 0, C = 1/2 (interpolating).
    pub const CATMULL_ROM: Filter = Filter::Bicubic { b: 0.0, c: 0.5 };
}

/// Where the texels of a radiosity texture sit in the polygon's (u, v) square, and so how the
/// texture filters map a coordinate to a texel position (per axis, N texels of a level).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Placement {
    /// Texel i at u = (i + 0.5) / N, the texel centres of a graphics texture; filters map u to
    /// x = u N - 0.5. The polygon's edges and corners lie half a texel outside the samples.
    #[default]
    Centre,
    /// The lightmap convention: texel i at u = i / (N - 1) (u = 0.5 for N = 1), so the first
    /// and last texels lie on the polygon's edges and the corner texels on its corners; filters
    /// map u to x = u (N - 1).
    Corner,
}

impl Placement {
    /// Every placement's name.
    pub const NAMES: &'static [&'static str] = &["centre", "corner"];

    /// Parses a placement name for the setting `option` (`texel-placement`, `render.texel_placement`);
    /// an unknown name is an [`Error::InvalidOption`] listing the known ones.
    pub fn parse_option(option: &str, name: &str) -> Result<Placement> {
        match name {
            "centre" => Ok(Placement::Centre),
            "corner" => Ok(Placement::Corner),
            _ => Err(Error::invalid_option(
                option,
                name,
                format!(
                    "is not a texel placement; known: {}",
                    Placement::NAMES.join(", ")
                ),
            )),
        }
    }

    /// The placement's name.
    pub fn name(self) -> &'static str {
        match self {
            Placement::Centre => "centre",
            Placement::Corner => "corner",
        }
    }

    /// Parameter coordinate of texel `k` of `n` on one axis, computed in f64 and rounded to f32:
    /// `(k + 0.5) / n` for [`Placement::Centre`], `k / (n - 1)` (0.5 if n = 1) for
    /// [`Placement::Corner`].
    #[inline]
    pub fn texel_position(self, k: u32, n: u32) -> f32 {
        match self {
            Placement::Centre => ((k as f64 + 0.5) / n as f64) as f32,
            Placement::Corner if n <= 1 => 0.5,
            Placement::Corner => (k as f64 / (n - 1) as f64) as f32,
        }
    }

    /// The affine map of the filters from a clamped coordinate u to the fractional texel
    /// position x = u scale - offset on an axis of `n` texels, as `(scale, offset)`:
    /// (n, 0.5) for [`Placement::Centre`], (n - 1, 0) for [`Placement::Corner`].
    #[inline(always)]
    pub fn texel_map(self, n: u32) -> (f32, f32) {
        match self {
            Placement::Centre => (n as f32, 0.5),
            Placement::Corner => (n.saturating_sub(1) as f32, 0.0),
        }
    }
}

/// The rendering methods. They share scene, solve, rasterization and composition; they differ
/// only in what the deferred pass evaluates (and, for the mesh, in what is rasterized).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// The PixelFlow path: bicubic RRP coefficients rasterized into region G-buffers and
    /// evaluated per pixel in the deferred pass.
    Direct,
    /// Radiosity textures (RAT) resampled from the RRPs, filtered on screen.
    Texture(Filter),
    /// The adaptively subdivided mesh (T-vertex fans), Gouraud shaded: the paper's "poly" model.
    Mesh,
    /// The solver's oracle at every visible sample: no reconstruction at all.
    Reference,
}

impl Method {
    /// Every implemented method's name.
    pub const NAMES: &'static [&'static str] = &[
        "direct",
        "texture-nearest",
        "texture-bilinear",
        "texture-bicubic",
        "mesh",
        "reference",
    ];

    /// Parses a method name (as on the command line and in `[render] method`);
    /// `texture-bicubic` is Mitchell–Netravali B = C = 1/3 (see [`Method::with_bicubic`]).
    /// An unknown name is an [`Error::InvalidOption`] for the setting `option`
    /// (`method`, `render.method`) listing the implemented ones.
    pub fn parse_option(option: &str, name: &str) -> Result<Method> {
        match name {
            "direct" => Ok(Method::Direct),
            "texture-nearest" => Ok(Method::Texture(Filter::Nearest)),
            "texture-bilinear" => Ok(Method::Texture(Filter::Bilinear)),
            "texture-bicubic" => Ok(Method::Texture(Filter::MITCHELL)),
            "mesh" => Ok(Method::Mesh),
            "reference" => Ok(Method::Reference),
            _ => Err(Error::invalid_option(
                option,
                name,
                format!("is not a method; implemented: {}", Method::NAMES.join(", ")),
            )),
        }
    }

    /// [`Method::parse_option`] for the command line's `--method`.
    pub fn parse(name: &str) -> Result<Method> {
        Method::parse_option("method", name)
    }

    /// The method's name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Direct => "direct",
            Method::Texture(Filter::Nearest) => "texture-nearest",
            Method::Texture(Filter::Bilinear) => "texture-bilinear",
            Method::Texture(Filter::Bicubic { .. }) => "texture-bicubic",
            Method::Mesh => "mesh",
            Method::Reference => "reference",
        }
    }

    /// This method with the bicubic filter's (B, C) replaced, if it is `texture-bicubic`; an
    /// error for B or C outside [0, 1] or not finite (the Mitchell–Netravali family's useful
    /// range; Catmull-Rom is (0, 1/2)).
    pub fn with_bicubic(self, b: f32, c: f32) -> Result<Method> {
        for (name, x) in [("B", b), ("C", c)] {
            if !(0.0..=1.0).contains(&x) {
                return Err(Error::invalid_option(
                    "bicubic",
                    format!("{b},{c}"),
                    format!("{name} = {x} must be in [0, 1]"),
                ));
            }
        }
        Ok(match self {
            Method::Texture(Filter::Bicubic { .. }) => Method::Texture(Filter::Bicubic { b, c }),
            m => m,
        })
    }
}

/// Samples per pixel of the renderer's patterns: 1, 4 or 16, checked once where the value enters
/// (an option or a scene key, [`Aa::new`]), so the stages that take one never check it again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Aa(u32);

impl Aa {
    /// One sample per pixel, at its centre.
    pub const ONE: Aa = Aa(1);

    /// `samples` per pixel, or an [`Error::InvalidOption`] naming `option` unless it is one of
    /// [`AA_SAMPLE_COUNTS`].
    pub fn new(option: &str, samples: u32) -> Result<Aa> {
        if AA_SAMPLE_COUNTS.contains(&samples) {
            Ok(Aa(samples))
        } else {
            Err(Error::invalid_option(
                option,
                samples.to_string(),
                "antialiasing takes 1, 4 or 16 samples per pixel",
            ))
        }
    }

    /// The number of samples per pixel (1, 4 or 16).
    pub fn samples(self) -> u32 {
        self.0
    }
}

impl Default for Aa {
    fn default() -> Self {
        Aa::ONE
    }
}

/// Checks a texture side named `option` (`texture-size`): a power of two in
/// `1..=`[`MAX_TEXTURE_SIZE`].
pub fn check_texture_side(option: &str, n: u32) -> Result<()> {
    if n == 0 || !n.is_power_of_two() || n > MAX_TEXTURE_SIZE {
        Err(Error::invalid_option(
            option,
            n.to_string(),
            format!("must be a power of two in 1..={MAX_TEXTURE_SIZE}"),
        ))
    } else {
        Ok(())
    }
}

/// Parses a byte count, the one size syntax of every option (`texture-budget`,
/// `memory-limit`): a number, decimals allowed, optionally followed by K, M, G or T (powers of
/// 1024), with or without `B` or `iB`, any case, spaces allowed before the unit (`2MB`, `1.5M`,
/// `8 GiB`, `4096`). At least 1 byte and below 2^64; the error names `option`.
pub fn parse_bytes(option: &str, text: &str) -> Result<u64> {
    size_in_bytes(text).map_err(|reason| Error::invalid_option(option, text, reason))
}

/// [`parse_bytes`] with the reason as text.
pub fn size_in_bytes(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    let lower = t.to_ascii_lowercase();
    if lower.starts_with('-') {
        return Err(format!(
            "`{t}` is negative: a size is a number of bytes, at least 1"
        ));
    }
    let split = lower
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(lower.len());
    let (num, unit) = lower.split_at(split);
    let shift = match unit.trim() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        u => {
            return Err(format!(
                "unknown unit `{u}`: write bytes, or a number with K, M, G or T"
            ))
        }
    };
    let x: f64 = num
        .parse()
        .map_err(|_| format!("`{t}` is not a size (for example 512M, 1.5GB or 8589934592)"))?;
    let bytes = x * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0) {
        return Err("must be at least 1 byte".into());
    }
    if bytes >= u64::MAX as f64 {
        return Err(format!(
            "`{t}` is 2^64 bytes or more, more than any machine addresses"
        ));
    }
    Ok(bytes as u64)
}

/// Parses `B,C` (two numbers) for `--bicubic`.
pub fn parse_bicubic(text: &str) -> Result<(f32, f32)> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    match parts.as_slice() {
        [b, c] => match (b.parse::<f32>(), c.parse::<f32>()) {
            (Ok(b), Ok(c)) => Ok((b, c)),
            _ => Err(Error::invalid_option(
                "bicubic",
                text,
                "B and C must be numbers",
            )),
        },
        _ => Err(Error::invalid_option(
            "bicubic",
            text,
            "expected B,C (Mitchell-Netravali 0.333,0.333; Catmull-Rom 0,0.5)",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for name in Method::NAMES {
            assert_eq!(Method::parse(name).unwrap().name(), *name);
        }
        let e = Method::parse("texturebilinear").unwrap_err();
        assert!(matches!(e, Error::InvalidOption { .. }));
        assert!(e
            .to_string()
            .starts_with("method texturebilinear: is not a method"));
        for name in Placement::NAMES {
            assert_eq!(Placement::parse_option("p", name).unwrap().name(), *name);
        }
        let e = Placement::parse_option("texel-placement", "edge").unwrap_err();
        assert!(matches!(e, Error::InvalidOption { .. }));
        assert!(e.to_string().starts_with("texel-placement edge:"));
        assert_eq!(Placement::default(), Placement::Centre);
    }

    #[test]
    fn texel_positions() {
        assert_eq!(Placement::Centre.texel_position(0, 4), 0.125);
        assert_eq!(Placement::Centre.texel_position(3, 4), 0.875);
        assert_eq!(Placement::Corner.texel_position(0, 4), 0.0);
        assert_eq!(Placement::Corner.texel_position(3, 4), 1.0);
        assert_eq!(Placement::Corner.texel_position(1, 3), 0.5);
        assert_eq!(Placement::Corner.texel_position(0, 1), 0.5);
        assert_eq!(Placement::Corner.texel_map(8), (7.0, 0.0));
        assert_eq!(Placement::Centre.texel_map(8), (8.0, 0.5));
    }

    #[test]
    fn option_checks() {
        for aa in AA_SAMPLE_COUNTS {
            assert_eq!(Aa::new("aa", aa).unwrap().samples(), aa);
        }
        let e = Aa::new("render.aa", 3).unwrap_err();
        assert!(e.to_string().contains("render.aa"), "{e}");
        check_texture_side("texture-size", 1).unwrap();
        check_texture_side("texture-size", MAX_TEXTURE_SIZE).unwrap();
        for bad in [0, 3, 2 * MAX_TEXTURE_SIZE] {
            assert!(check_texture_side("texture-size", bad).is_err());
        }
        assert_eq!(parse_bytes("b", "4M").unwrap(), 4 << 20);
        assert_eq!(parse_bytes("b", "512k").unwrap(), 512 << 10);
        assert_eq!(parse_bytes("b", "17").unwrap(), 17);
        // One syntax for every size option: units with and without B, decimals, spaces.
        assert_eq!(parse_bytes("b", "2MB").unwrap(), 2 << 20);
        assert_eq!(parse_bytes("b", "1.5M").unwrap(), 3 << 19);
        assert_eq!(parse_bytes("b", "8 GiB").unwrap(), 8 << 30);
        for bad in ["", "M", "-1", "0.1", "5X", "99999999999G"] {
            assert!(parse_bytes("b", bad).is_err(), "{bad}");
        }
        assert_eq!(parse_bicubic("0, 0.5").unwrap(), (0.0, 0.5));
        assert!(parse_bicubic("1").is_err());
        assert!(Method::Texture(Filter::MITCHELL)
            .with_bicubic(1.5, 0.0)
            .is_err());
        assert!(Method::Texture(Filter::MITCHELL)
            .with_bicubic(f32::NAN, 0.0)
            .is_err());
        assert_eq!(
            Method::Texture(Filter::MITCHELL)
                .with_bicubic(0.0, 0.5)
                .unwrap(),
            Method::Texture(Filter::CATMULL_ROM)
        );
    }
}
