//! Deterministic mutation test of the input readers, run on every `cargo test`.
//!
//! The shipped files (every `scenes/*.toml`, the Cornell box and gallery OBJ/MTL) and a solution
//! file encoded here from a small solved scene are mutated with a fixed-seed splitmix64
//! generator: bit and byte flips, byte-range and line deletes and duplicates, line swaps,
//! splices of lines from the other files, numbers replaced by extremes (`0`, `-0`, `1e308`,
//! `nan`, `inf`, `4294967296`, `18446744073709551616`, long digit strings, ...), emptied strings
//! and truncations. Every mutant goes through the loader inside `catch_unwind`, and:
//!
//! - nothing panics, and no input takes more than [`SLOW`] to refuse or load;
//! - an error has a non-empty message and is bad input (exit code 2);
//! - a parse error of a scene, OBJ or MTL file names the file (one of the files of the case,
//!   at the start of the message), and a solution-file error names the solution file;
//! - a mutated scene that loads also passes what `check` does (the summary).
//!
//! OBJ/MTL mutants are written to a temporary directory with a scene that includes them.
//! Solution mutants are decoded both as they are and with their envelope repaired (version,
//! lengths, scene hash and checksum made valid, so the payload decoder sees the damage), then
//! reconstructed the way `render` does (the compact RRPs built from the samples)
//! and through the real `prepare_path`.
//!
//! Counts: [`SCENE_CASES`] + [`OBJ_CASES`] + [`SOLUTION_CASES`] = 7200 mutants, 10 s in
//! `cargo test --release` on 2 cores shared with two fuzzers (half the counts took 4.4 s); most
//! of it is loading the 2000-line gallery OBJ.

use app::context::Context;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use app::context::TextureOptions;
use app::prepare::prepare_path;
use base::error::{Error, EXIT_BAD_INPUT};
use radiosity::{self, file, SolveOptions};
use reconstruction::compact::CompactReconstruction;
use reconstruction::Estimator;
use scene::{load_scene, parse_scene, Scene};

/// Mutants of the scene files.
const SCENE_CASES: usize = 3000;
/// Mutants of the OBJ/MTL pairs.
const OBJ_CASES: usize = 2600;
/// Mutants of the solution file.
const SOLUTION_CASES: usize = 1600;
/// Longest time one mutant may take: a hang is a failure, not a slow test. A mutant takes
/// milliseconds alone; beside the other test binaries on a loaded 2-core machine one took 2.2 s,
/// so the guard sits an order of magnitude above that.
const SLOW: Duration = Duration::from_secs(20);

// ---------------------------------------------------------------------------------------------
// The generator and the mutations.

/// The project's seeded generator (SplitMix64), with the picks mutations need.
struct Rng(base::rng::Rng);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in `0..n` (`n > 0`).
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Numbers that break parsers and arithmetic: zeros, extremes, subnormals, non-finite values,
/// integers just past u32 and u64, and digit strings longer than any type.
fn extremes() -> Vec<String> {
    let mut v: Vec<String> = [
        "0",
        "-0",
        "-0.0",
        "1e308",
        "-1e308",
        "1e-320",
        "nan",
        "-nan",
        "inf",
        "-inf",
        "4294967296",
        "-4294967296",
        "18446744073709551616",
        "9223372036854775807",
        "-9223372036854775808",
        "2147483648",
        "65536",
        "1e9",
        "-1",
        "0.5",
        "",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    v.push("9".repeat(400));
    v.push(format!("0.{}1", "0".repeat(400)));
    v.push(format!("1{}", "0".repeat(40)));
    v
}

/// Byte ranges of the number literals of `text` (digits with signs, dots and exponents).
fn numbers(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let c = text[i];
        let starts = c.is_ascii_digit()
            || ((c == b'-' || c == b'.') && text.get(i + 1).is_some_and(|d| d.is_ascii_digit()));
        if starts && (i == 0 || !text[i - 1].is_ascii_alphanumeric()) {
            let a = i;
            i += 1;
            while i < text.len()
                && matches!(text[i], b'0'..=b'9' | b'.' | b'e' | b'E' | b'-' | b'+')
            {
                i += 1;
            }
            out.push((a, i));
        } else {
            i += 1;
        }
    }
    out
}

/// Byte ranges of the insides of the `"..."` strings of `text`.
fn strings(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut open = None;
    for (i, &c) in text.iter().enumerate() {
        if c == b'\n' {
            open = None;
        } else if c == b'"' {
            match open.take() {
                Some(a) => out.push((a, i)),
                None => open = Some(i + 1),
            }
        }
    }
    out
}

/// Byte ranges of the lines of `text`, each with its newline.
fn lines(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut a = 0;
    for (i, &c) in text.iter().enumerate() {
        if c == b'\n' {
            out.push((a, i + 1));
            a = i + 1;
        }
    }
    if a < text.len() {
        out.push((a, text.len()));
    }
    out
}

/// Applies one random text mutation to `t`; `donors` are lines of the other files.
fn mutate_text(rng: &mut Rng, t: &mut Vec<u8>, donors: &[Vec<u8>], extremes: &[String]) {
    if t.is_empty() {
        let d: &Vec<u8> = rng.pick(donors);
        t.extend_from_slice(d);
        return;
    }
    let n = t.len();
    match rng.below(11) {
        // A flipped bit, or a byte replaced by a random one.
        0 => {
            let i = rng.below(n);
            t[i] ^= 1 << rng.below(8);
        }
        1 => {
            let i = rng.below(n);
            t[i] = rng.next() as u8;
        }
        // A byte range deleted or duplicated.
        2 => {
            let a = rng.below(n);
            let b = (a + 1 + rng.below(16)).min(n);
            t.drain(a..b);
        }
        3 => {
            let a = rng.below(n);
            let b = (a + 1 + rng.below(16)).min(n);
            let dup = t[a..b].to_vec();
            t.splice(b..b, dup);
        }
        // A line deleted, duplicated, or swapped with another.
        4..=6 => {
            let ls = lines(t);
            let (a, b) = *rng.pick(&ls);
            match rng.below(3) {
                0 => {
                    t.drain(a..b);
                }
                1 => {
                    let dup = t[a..b].to_vec();
                    t.splice(b..b, dup);
                }
                _ => {
                    let (c, d) = *rng.pick(&ls);
                    if b <= c {
                        let second = t[c..d].to_vec();
                        let first = t[a..b].to_vec();
                        t.splice(c..d, first);
                        t.splice(a..b, second);
                    }
                }
            }
        }
        // A line of another file spliced in.
        7 => {
            let ls = lines(t);
            let (a, _) = *rng.pick(&ls);
            let d: &Vec<u8> = rng.pick(donors);
            t.splice(a..a, d.iter().copied());
        }
        // A number replaced by an extreme.
        8 | 9 => {
            let ns = numbers(t);
            if ns.is_empty() {
                return;
            }
            let (a, b) = *rng.pick(&ns);
            t.splice(a..b, rng.pick(extremes).bytes());
        }
        // A string emptied, or a truncation.
        _ => {
            let ss = strings(t);
            if rng.below(2) == 0 && !ss.is_empty() {
                let (a, b) = *rng.pick(&ss);
                t.drain(a..b);
            } else {
                t.truncate(rng.below(n));
            }
        }
    }
}

/// Applies one random binary mutation to the solution bytes `b`.
fn mutate_bytes(rng: &mut Rng, b: &mut Vec<u8>) {
    if b.is_empty() {
        b.push(rng.next() as u8);
        return;
    }
    let n = b.len();
    match rng.below(7) {
        0 => {
            let i = rng.below(n);
            b[i] ^= 1 << rng.below(8);
        }
        1 => {
            let a = rng.below(n);
            let e = (a + 1 + rng.below(32)).min(n);
            b.drain(a..e);
        }
        2 => {
            let a = rng.below(n);
            let e = (a + 1 + rng.below(32)).min(n);
            let dup = b[a..e].to_vec();
            b.splice(e..e, dup);
        }
        3 => b.truncate(rng.below(n)),
        // An extreme 32-bit word (a count, an index, a level, an f32) at a 4-aligned offset.
        4 => {
            let words: [u32; 9] = [
                0,
                1,
                2,
                u32::MAX,
                0x8000_0000,
                0x7fff_ffff,
                f32::NAN.to_bits(),
                f32::INFINITY.to_bits(),
                (-1.0f32).to_bits(),
            ];
            let i = rng.below(n / 4) * 4;
            let w = rng.pick(&words).to_le_bytes();
            let e = (i + 4).min(n);
            b[i..e].copy_from_slice(&w[..e - i]);
        }
        // An extreme 64-bit value (a length, a total, a statistic).
        5 => {
            let words: [u64; 6] = [
                0,
                u64::MAX,
                1 << 63,
                f64::NAN.to_bits(),
                f64::MAX.to_bits(),
                (-0.0f64).to_bits(),
            ];
            let i = rng.below(n);
            let w = rng.pick(&words).to_le_bytes();
            let e = (i + 8).min(n);
            b[i..e].copy_from_slice(&w[..e - i]);
        }
        // An extreme 16-bit value (a compact RRP exponent or mantissa).
        _ => {
            let words: [u16; 5] = [0, 0x8000, 0x7fff, 0xffff, 0x7f00];
            let i = rng.below(n / 2) * 2;
            let w = rng.pick(&words).to_le_bytes();
            let e = (i + 2).min(n);
            b[i..e].copy_from_slice(&w[..e - i]);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Running one mutant.

fn scenes() -> PathBuf {
    Path::new(crate::REPO).join("scenes")
}

/// A scratch directory for this test run, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Scratch {
        let d = std::env::temp_dir().join(format!("pfs-mutations-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Scratch(d)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs `f` on one mutant: no panic, no hang. `what` describes the mutant for the failure.
fn guarded<T>(what: &dyn Fn() -> String, f: impl FnOnce() -> T) -> T {
    let t = Instant::now();
    let out = catch_unwind(AssertUnwindSafe(f))
        .unwrap_or_else(|_| panic!("the loader panicked on {}", what()));
    let took = t.elapsed();
    assert!(took < SLOW, "{took:?} on {}", what());
    out
}

/// The loader's answer for a scene, OBJ or MTL mutant: a scene that passes `check`, or an input
/// error naming one of `files`.
fn loaded_or_refused(r: base::Result<Scene>, files: &[PathBuf], what: &dyn Fn() -> String) {
    match r {
        Ok(s) => {
            assert!(!s.polygons.is_empty(), "{}", what());
            let summary = app::report::summarize(&s).to_string();
            assert!(!summary.is_empty(), "{}", what());
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.is_empty(), "empty message for {}", what());
            assert_eq!(e.exit_code(), EXIT_BAD_INPUT, "{msg} for {}", what());
            let Error::Input { location, message } = &e else {
                panic!("not an input error: {msg} for {}", what());
            };
            assert!(!message.is_empty(), "{msg} for {}", what());
            assert!(
                files.contains(&location.file),
                "the error names none of the case's files: {msg} for {}",
                what()
            );
            assert!(
                msg.starts_with(&location.file.display().to_string()),
                "{msg} for {}",
                what()
            );
        }
    }
}

/// Shows a mutant for a failure message (the start of it, lossily).
fn show(b: &[u8]) -> String {
    let t = String::from_utf8_lossy(b);
    let cut: String = t.chars().take(3000).collect();
    format!("mutant ({} bytes):\n{cut}", b.len())
}

/// Lines of every shipped text file, as splice donors.
fn donor_lines(texts: &[Vec<u8>]) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for t in texts {
        for (a, b) in lines(t) {
            out.push(t[a..b].to_vec());
        }
    }
    out
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The shipped scene files, but for the generated `building.toml`: its syntax is the gallery's,
/// and loading its 10,048 polygons for every sixth mutant would add over 10 s (500 loads of
/// about 30 ms).
fn scene_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(scenes())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .filter(|p| !p.ends_with("building.toml"))
        .collect();
    v.sort();
    assert!(v.len() >= 4, "{v:?}");
    v
}

/// The shipped OBJ files and their MTL files.
fn obj_pairs() -> Vec<(PathBuf, PathBuf)> {
    let d = scenes();
    vec![
        (
            d.join("cornell-box/CornellBox-Original.obj"),
            d.join("cornell-box/CornellBox-Original.mtl"),
        ),
        (d.join("gallery/gallery.obj"), d.join("gallery/gallery.mtl")),
    ]
}

// ---------------------------------------------------------------------------------------------
// The tests.

#[test]
fn mutated_scene_files_are_loaded_or_refused_with_their_file() {
    let files = scene_files();
    let texts: Vec<Vec<u8>> = files.iter().map(|p| read(p)).collect();
    let mut all = texts.clone();
    all.extend(obj_pairs().iter().flat_map(|(o, m)| [read(o), read(m)]));
    let donors = donor_lines(&all);
    let extremes = extremes();
    // Every file an error may name: the scene itself, and the shipped includes.
    let mut known = files.clone();
    known.extend(obj_pairs().into_iter().flat_map(|(o, m)| [o, m]));
    let mut rng = Rng(base::rng::Rng::new(0x5eed_0001));
    let mut loaded = 0;
    for case in 0..SCENE_CASES {
        let k = case % files.len();
        let mut t = texts[k].clone();
        for _ in 0..1 + rng.below(3) {
            mutate_text(&mut rng, &mut t, &donors, &extremes);
        }
        let what = || format!("case {case} of {}: {}", files[k].display(), show(&t));
        let text = String::from_utf8_lossy(&t);
        let r = guarded(&what, || parse_scene(&text, &files[k]));
        loaded += usize::from(r.is_ok());
        loaded_or_refused(r, &known, &what);
    }
    // The mutations are neither all fatal nor all harmless.
    assert!(
        loaded > SCENE_CASES / 20 && loaded < SCENE_CASES,
        "{loaded} loaded"
    );
}

#[test]
fn mutated_obj_and_mtl_files_are_loaded_or_refused_with_their_file() {
    let pairs = obj_pairs();
    let texts: Vec<(Vec<u8>, Vec<u8>)> = pairs.iter().map(|(o, m)| (read(o), read(m))).collect();
    let mut all: Vec<Vec<u8>> = texts
        .iter()
        .flat_map(|(o, m)| [o.clone(), m.clone()])
        .collect();
    all.extend(scene_files().iter().map(|p| read(p)));
    let donors = donor_lines(&all);
    let extremes = extremes();
    let dir = Scratch::new("obj");
    let scene = dir.0.join("s.toml");
    std::fs::write(&scene, fixtures::hostile::obj_host_scene("m.obj")).unwrap();
    let obj = dir.0.join("m.obj");
    let mut rng = Rng(base::rng::Rng::new(0x5eed_0002));
    let mut loaded = 0;
    for case in 0..OBJ_CASES {
        let k = case % pairs.len();
        // The MTL under the name the shipped OBJ's `mtllib` gives.
        let mtl = dir.0.join(pairs[k].1.file_name().unwrap());
        let (mut o, mut m) = texts[k].clone();
        for _ in 0..1 + rng.below(3) {
            match rng.below(3) {
                0 => mutate_text(&mut rng, &mut m, &donors, &extremes),
                _ => mutate_text(&mut rng, &mut o, &donors, &extremes),
            }
        }
        std::fs::write(&obj, &o).unwrap();
        std::fs::write(&mtl, &m).unwrap();
        let what = || {
            format!(
                "case {case} of {}: OBJ {}\nMTL {}",
                pairs[k].0.display(),
                show(&o),
                show(&m)
            )
        };
        let r = guarded(&what, || load_scene(&scene));
        loaded += usize::from(r.is_ok());
        loaded_or_refused(r, &[scene.clone(), obj.clone(), mtl.clone()], &what);
        std::fs::remove_file(&mtl).unwrap();
    }
    assert!(
        loaded > OBJ_CASES / 20 && loaded < OBJ_CASES,
        "{loaded} loaded"
    );
}

/// A small scene to solve in-test: a floor, a wall and an emitting square, depth at most 3.
const SOLVED_SCENE: &str = r#"[camera]
eye = [0.5, 2.0, 2.5]
look_at = [0.5, 0.0, 0.5]
fov_y = 45.0

[[materials]]
name = "floor"
reflectance = [0.6, 0.5, 0.4]

[[materials]]
name = "lamp"
reflectance = [0.2, 0.2, 0.2]
emission = [2.0, 2.0, 2.0]

[[polygons]]
vertices = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
material = "floor"

[[polygons]]
vertices = [[0.4, 1.0, 0.4], [0.6, 1.0, 0.4], [0.6, 1.0, 0.6], [0.4, 1.0, 0.6]]
material = "lamp"

[[polygons]]
vertices = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]
material = "floor"

[[spots]]
position = [0.8, 0.8, 0.8]
direction = [0.0, -1.0, 0.0]
intensity = [0.5, 0.5, 0.5]
half_angle = 45.0

[radiosity]
tolerance = 0.05
min_depth = 1
max_depth = 3
convergence = 0.05
shadow_rays = 1
seed = 1
"#;

#[test]
fn mutated_solution_files_are_read_or_refused_as_bad_solutions() {
    let dir = Scratch::new("solution");
    let scene_path = dir.0.join("small.toml");
    std::fs::write(&scene_path, SOLVED_SCENE).unwrap();
    let scene = load_scene(&scene_path).unwrap();
    let sol = radiosity::solve(&scene, &SolveOptions::default()).unwrap();
    // The file as `solve` writes it (with the scene path).
    let abs = std::fs::canonicalize(&scene_path).unwrap();
    let original = file::encode_with_scene(&sol, Some(&abs));
    assert!(file::decode(&original, &scene).is_ok());
    let pfsol = dir.0.join("m.pfsol");
    let mut rng = Rng(base::rng::Rng::new(0x5eed_0003));
    let (mut decoded, mut prepared) = (0, 0);
    for case in 0..SOLUTION_CASES {
        let mut b = original.clone();
        for _ in 0..1 + rng.below(3) {
            mutate_bytes(&mut rng, &mut b);
        }
        if case % 4 != 3 {
            file::reseal(&mut b, &scene);
        }
        let what = || format!("solution case {case} ({} bytes): {b:?}", b.len());
        // In memory: decode, then what `render` and `--estimator` reconstruct from it.
        let d = guarded(&what, || match file::decode(&b, &scene) {
            Ok(s) => {
                if let Ok(c) = CompactReconstruction::build(&s.polygons, Estimator::default()) {
                    for id in 0..c.leaf_count() as u32 {
                        let _ = c.expand(id);
                    }
                }
                true
            }
            Err(file::Bad(_, message)) => {
                assert!(!message.is_empty(), "{}", what());
                false
            }
        });
        decoded += usize::from(d);
        // Through the file, as `render <file>` prepares it.
        std::fs::write(&pfsol, &b).unwrap();
        let r = guarded(&what, || {
            prepare_path(&Context::default(), &pfsol, &TextureOptions::default()).map(|_| ())
        });
        match r {
            Ok(()) => prepared += 1,
            Err(e) => {
                let msg = e.to_string();
                assert_eq!(e.exit_code(), EXIT_BAD_INPUT, "{msg} for {}", what());
                if let Error::Solution { path, message, .. } = &e {
                    assert_eq!(path, &pfsol, "{msg}");
                    assert!(!message.is_empty(), "{}", what());
                } else {
                    // A damaged scene path names a file that is missing or not a scene.
                    assert!(matches!(e, Error::Input { .. }), "{msg} for {}", what());
                }
            }
        }
    }
    assert!(decoded > 0 && decoded < SOLUTION_CASES, "{decoded} decoded");
    assert!(
        prepared <= decoded,
        "{prepared} prepared, {decoded} decoded"
    );
}
