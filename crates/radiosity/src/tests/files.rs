//! What a solve writes: the oracle returns its samples, threads and caches change no byte, the
//! solution file round-trips and refuses what is not one, settings are checked.

use std::sync::atomic::Ordering;

use super::*;

/// The oracle reproduces every stored sample bit for bit (they are the same computation).
#[test]
fn oracle_returns_stored_samples_exactly() {
    let (s, sol) = cornell_solution();
    let o = Oracle::new(sol, s).expect("oracle");
    let mut n = 0;
    for (p, k, v) in samples(sol).step_by(53) {
        let got = o.radiosity(p, k.u(), k.v());
        assert_eq!(
            got.to_array().map(f32::to_bits),
            v.to_array().map(f32::to_bits)
        );
        n += 1;
    }
    assert!(n > 50);
    let (p, k, v) = samples(sol).nth(17).expect("a sample");
    assert_eq!(sol.radiosity(s, p, k.u(), k.v()), v);
    // Between samples the oracle still answers, finite and non-negative.
    let b = o.radiosity(0, 0.123, 0.456);
    assert!(b.is_finite() && b.min_element() >= 0.0 && b.max_element() > 0.0);
}

/// A smaller Cornell box solved in pools of 1 and 2 threads gives byte-identical files.
#[test]
fn one_and_two_threads_give_identical_files() {
    let mut s = cornell();
    s.radiosity.max_depth = 5;
    s.radiosity.shadow_rays = 8;
    let bytes = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        let sol = pool.install(|| solve_quiet(&s));
        file::encode(&sol)
    };
    let a = bytes(1);
    let b = bytes(2);
    assert!(a.len() > 1000);
    assert!(a == b, "1- and 2-thread solutions differ");
}

/// The coarse-shot cache changes nothing: the Cornell box solved with no cache room gives the
/// same trees, samples, shot count and history totals, bit for bit (a cached shot adds the same
/// f32-rounded transfers a computed one does), while patches do shoot more than once (so the
/// default run really reuses cached transfers).
#[test]
fn coarse_cache_changes_nothing() {
    let mut s = cornell();
    s.radiosity.max_depth = 4;
    let run = |entries: usize| {
        let mut tr = transfer::Transfer::new(&s);
        shoot::run_with_caches(
            &s,
            &mut tr,
            &mut Stage::start(&SILENT, STAGE),
            (entries, 0),
            u64::MAX,
        )
        .expect("solve")
    };
    let a = run(0);
    let b = run(shoot::COARSE_CACHE_ENTRIES);
    assert_same_solve(&a, &b);
    let shooters_with_total = a.totals.iter().filter(|t| **t != DVec3::ZERO).count() as u64;
    assert!(a.shots > shooters_with_total, "{} shots", a.shots);
}

/// What the gathers keep of the geometry at each point changes nothing: solved with no room
/// for it, the Cornell box and a room whose ceiling light falls through a grid of 64 tiles
/// (more occluders than the exact query takes: shadow rays decide there) give the same trees,
/// samples, shots and history, bit for bit, and write the same solution file; with room, they
/// answer fewer visibility queries (the regions of partly seen patches kept too), and with room
/// for part of it, fewer than without and more than with room for all.
#[test]
fn kept_geometry_changes_nothing() {
    let mut cornell = cornell();
    cornell.radiosity.max_depth = 4;
    let mut grid = closed_room_with_box();
    grid.polygons.truncate(6);
    for i in 0..8 {
        for j in 0..8 {
            let (x, y) = (0.12 + 0.22 * i as f64, 0.12 + 0.22 * j as f64);
            let c = [
                DVec3::new(x, y, 1.4),
                DVec3::new(x + 0.15, y, 1.4),
                DVec3::new(x + 0.15, y + 0.15, 1.4),
                DVec3::new(x, y + 0.15, 1.4),
            ];
            grid.polygons
                .push(quad_facing(c, DVec3::new(1.0, 1.0, 0.0), 2));
        }
    }
    grid.radiosity.max_depth = 4;
    for s in [&cornell, &grid] {
        let run = |seen: u64| {
            let mut tr = transfer::Transfer::new(s);
            let out = shoot::run_with_caches(
                s,
                &mut tr,
                &mut Stage::start(&SILENT, STAGE),
                (shoot::COARSE_CACHE_ENTRIES, seen),
                u64::MAX,
            )
            .expect("solve");
            let counts = (
                tr.exact_queries.load(Ordering::Relaxed),
                tr.ray_fallbacks.load(Ordering::Relaxed),
            );
            (out, counts)
        };
        let (a, (exact_a, rays_a)) = run(0);
        let (b, (exact_b, rays_b)) = run(64 << 20);
        assert_same_solve(&a, &b);
        // Room for some points and their regions, not for all.
        let (c, (exact_c, _)) = run(1 << 20);
        assert_same_solve(&a, &c);
        assert!(
            exact_b < exact_c && exact_c < exact_a,
            "{exact_a} {exact_c} {exact_b}"
        );
        assert!(
            exact_b < exact_a && rays_b <= rays_a,
            "queries {exact_a} -> {exact_b}, ray fallbacks {rays_a} -> {rays_b}"
        );
        if std::ptr::eq(s, &grid) {
            assert!(
                rays_b < rays_a,
                "the grid's rays are kept: {rays_a} -> {rays_b}"
            );
            assert!(a.rays > b.rays, "rays cast {} -> {}", a.rays, b.rays);
        }
        // Regression: the rays cast, which the kept geometry's room decides, were stored, so
        // two solves under different memory limits wrote different solution files.
        let start = std::time::Instant::now();
        let (fa, fb) = (
            file::encode(&crate::solution_of(s, a, start)),
            file::encode(&crate::solution_of(s, b, start)),
        );
        assert!(
            fa == fb,
            "the solution files differ with the kept geometry's room"
        );
    }
}

/// Two solves of one scene gave the same shots, totals, history, trees and samples, bit for
/// bit.
fn assert_same_solve(a: &shoot::Outcome, b: &shoot::Outcome) {
    assert_eq!(a.shots, b.shots);
    assert_eq!(a.totals, b.totals);
    assert_eq!(a.history, b.history);
    assert!(a
        .trees
        .iter()
        .zip(&b.trees)
        .all(|(x, y)| x.1 == y.1 && x.2 == y.2));
}

fn tmp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir()
        .join(format!("pfs-solver-{}", std::process::id()))
        .join(name)
}

fn input_message(e: Error) -> String {
    match e {
        Error::Input { message, .. } => message,
        other => panic!("expected an input error, got {other:?}"),
    }
}

fn solution_problem(e: Error) -> (base::error::SolutionProblem, String) {
    match e {
        Error::Solution {
            problem, message, ..
        } => (problem, message),
        other => panic!("expected a solution file error, got {other:?}"),
    }
}

#[test]
fn solution_file_round_trip_and_errors() {
    let mut s = two_spots();
    s.radiosity.max_depth = 4;
    let mut sol = solve_quiet(&s);
    let path = tmp("a.pfsol");
    file::write_solution(&base::output::Outputs::new(), &path, &sol, None).expect("write");
    let back = file::read_solution(&path, &s).expect("read");
    sol.stats.solve_ms = 0.0;
    sol.stats.rays_cast = 0;
    // Node order included: the solve hands out its trees in the canonical order the file's
    // split bits rebuild.
    assert_eq!(back, sol);
    let bytes = std::fs::read(&path).expect("bytes");
    // One split bit per node and three f32 per vertex, as the format says.
    let bits: usize = sol
        .polygons
        .iter()
        .map(|p| p.tree.nodes().len().div_ceil(8))
        .sum();
    let vertices: usize = sol.polygons.iter().map(|p| p.values.len()).sum();
    assert_eq!(
        file::samples_bytes(&sol),
        (4 + 4 * sol.polygons.len() + bits + 12 * vertices) as u64
    );

    use base::error::SolutionProblem as P;
    let p = tmp("trunc.pfsol");
    std::fs::write(&p, &bytes[..bytes.len() - 10]).expect("w");
    let (k, m) = solution_problem(file::read_solution(&p, &s).unwrap_err());
    assert!(k == P::Truncated && m.contains("truncated"), "{m}");

    let mut flipped = bytes.clone();
    flipped[bytes.len() / 2] ^= 0x10;
    std::fs::write(&p, &flipped).expect("w");
    let (k, m) = solution_problem(file::read_solution(&p, &s).unwrap_err());
    assert!(k == P::Corrupt && m.contains("checksum"), "{m}");

    let mut other = bytes.clone();
    other[8] = 99;
    std::fs::write(&p, &other).expect("w");
    let (k, m) = solution_problem(file::read_solution(&p, &s).unwrap_err());
    assert_eq!(
        k,
        P::Version {
            found: 99,
            supported: file::FORMAT_VERSION
        }
    );
    assert!(m.contains("version 99"), "{m}");

    // Older versions (1: before the stored RRPs; 2: before the local refinement criterion,
    // per-channel convergence and the Hyman estimator) are refused with the same clear message.
    for old in [1u32, 2] {
        let mut v = bytes.clone();
        v[8..12].copy_from_slice(&old.to_le_bytes());
        std::fs::write(&p, &v).expect("w");
        let (k, m) = solution_problem(file::read_solution(&p, &s).unwrap_err());
        assert_eq!(
            k,
            P::Version {
                found: old,
                supported: file::FORMAT_VERSION
            }
        );
        assert!(m.contains("solve the scene again"), "{m}");
    }
    let mut v1 = bytes.clone();
    v1[8..12].copy_from_slice(&1u32.to_le_bytes());
    std::fs::write(&p, &v1).expect("w");
    let (_, m) = solution_problem(file::read_solution(&p, &s).unwrap_err());
    assert!(
        m.contains("version 1") && m.contains("solve the scene again"),
        "{m}"
    );

    let mut s2 = s.clone();
    s2.materials[0].reflectance.x = 0.4;
    let (k, m) = solution_problem(file::read_solution(&path, &s2).unwrap_err());
    assert!(k == P::SceneMismatch && m.contains("another scene"), "{m}");

    std::fs::write(&p, b"hello").expect("w");
    let (k, m) = solution_problem(file::read_solution(&p, &s).unwrap_err());
    assert!(k == P::NotASolution && m.contains("magic"), "{m}");
    let _ = std::fs::remove_dir_all(path.parent().expect("dir"));
}

/// A node count the data cannot hold is refused before any tree is grown. With one bit per node,
/// a count the bits alone allowed would have grown a tree about a hundred times the file's size
/// before its samples were found missing: every vertex needs 12 bytes, and a tree has at least
/// as many vertices as leaves.
#[test]
fn a_node_count_the_samples_cannot_hold_is_refused() {
    let mut s = two_spots();
    s.radiosity.max_depth = 3;
    let bytes = file::encode(&solve_quiet(&s));
    // No scene path: the payload starts after the 32-byte header, polygon 0's node count after
    // the polygon count.
    let at = 32 + 4;
    let rest = bytes.len() - 8 - (at + 4);
    for nn in [
        4 * (rest / 4) + 1,
        4 * (4 * rest / 4) + 1,
        4 * (1 << 28) + 1,
    ] {
        let mut b = bytes.clone();
        b[at..at + 4].copy_from_slice(&(nn as u32).to_le_bytes());
        file::reseal(&mut b, &s);
        match file::decode(&b, &s) {
            Err(file::Bad(base::error::SolutionProblem::Corrupt, m)) => {
                assert!(m.contains("runs past the end"), "{nn}: {m}")
            }
            Err(file::Bad(p, m)) => panic!("{nn}: {p:?}: {m}"),
            Ok(_) => panic!("{nn} nodes accepted"),
        }
    }
}

/// A solution file decodes to several times its bytes, so a job's input cap admits a smaller
/// solution file than it admits a scene file: one of the cap's size is refused before it is
/// read whole, one of 2/5 of it is read.
#[test]
fn the_input_cap_counts_what_a_solution_decodes_to() {
    let mut s = two_spots();
    s.radiosity.max_depth = 3;
    let path = tmp("cap.pfsol");
    file::write_solution(&base::output::Outputs::new(), &path, &solve_quiet(&s), None)
        .expect("write");
    let len = std::fs::metadata(&path).expect("metadata").len();
    let (k, m) = solution_problem(file::read_solution_up_to(&path, &s, len).unwrap_err());
    assert_eq!(k, base::error::SolutionProblem::NotASolution, "{m}");
    assert!(m.contains("cannot read"), "{m}");
    let fits = len * (1 + file::DECODED_PER_FILE_BYTE) / 2 + 1;
    assert!(file::read_solution_up_to(&path, &s, fits).is_ok());
    let _ = std::fs::remove_file(&path);
}

#[test]
fn bad_settings_are_input_errors() {
    let mut s = spot_over_plane();
    s.radiosity.shadow_rays = 0;
    let m = input_message(solve(&s, &SolveOptions::default()).unwrap_err());
    assert!(m.contains("shadow_rays") || m.contains("1..="), "{m}");
    let mut s = spot_over_plane();
    s.radiosity.min_depth = 9;
    s.radiosity.max_depth = 3;
    // Rejected before the stage starts: the observer hears nothing.
    let r = Recorder::tracing();
    assert!(solve(
        &s,
        &SolveOptions {
            observer: &r,
            ..SolveOptions::default()
        }
    )
    .is_err());
    assert!(r.events().is_empty(), "{:?}", r.events());
}

/// `radiosity.visibility = "auto"` (the default) is not part of the scene's hash; `exact` and
/// `sampled` are (they change the solution).
#[test]
fn the_visibility_setting_is_hashed_unless_auto() {
    let base = cornell();
    let with = |v: scene::Visibility| {
        let mut s = base.clone();
        s.radiosity.visibility = v;
        scene_hash(&s)
    };
    use scene::Visibility::{Auto, Exact, Sampled};
    assert_eq!(with(Auto), scene_hash(&base));
    assert_ne!(with(Auto), with(Exact));
    assert_ne!(with(Exact), with(Sampled));
    assert_ne!(with(Auto), with(Sampled));
}
