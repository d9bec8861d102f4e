//! What a solve reports while it runs: progress, traces, snapshots, and the memory limit that
//! stops refinement.

use super::*;

/// Timings of the code-built scenes (printed with `--nocapture`); asserts only what any solve
/// must satisfy, so it does not depend on machine load.
#[test]
fn timing_report() {
    for (name, s) in [("two-spots", two_spots()), ("cornell", cornell())] {
        let sol = if name == "cornell" {
            cornell_solution().1.clone()
        } else {
            solve_quiet(&s)
        };
        let st = &sol.stats;
        eprintln!(
            "{name}: polygons {} solve {:.0} ms vertices {} leaves {} T-vertices {} shots {} rays {} unshot {:.4} depths {:?}",
            s.polygons.len(), st.solve_ms, st.vertices, st.elements, st.t_vertices, st.shots,
            st.rays_cast, st.unshot_fraction, st.depth_histogram
        );
        eprintln!(
            "  unshot history {:?}",
            &st.unshot_history[..st.unshot_history.len().min(12)]
        );
        assert!(st.unshot_fraction < s.radiosity.convergence);
        assert!(samples(&sol).all(|(_, _, v)| v.is_finite() && v.min_element() >= 0.0));
    }
}

/// Splits what a recorder received into the solve's progress fractions and trace lines, checking
/// that every progress event belongs to the solve stage, that the fractions start at 0, stay in
/// [0, 1], never decrease and reach 1, and that the last event is the one `finished("solve")`.
fn observed(events: &[Event]) -> (Vec<f64>, Vec<String>) {
    let (mut fractions, mut lines) = (Vec::new(), Vec::new());
    let (last, rest) = events.split_last().expect("events");
    assert_eq!(*last, Event::Finished(STAGE.into()));
    for e in rest {
        match e {
            Event::Progress(stage, f) => {
                assert_eq!(stage, STAGE);
                fractions.push(*f);
            }
            Event::Trace(line) => lines.push(line.clone()),
            Event::Finished(stage) => panic!("finished({stage}) before the end"),
            // Remaining-time estimates come from clocks: checked for sanity only.
            Event::Remaining(phase, secs) => {
                assert!(phase.starts_with("round "), "{phase}");
                assert!(secs.is_finite() && *secs >= 0.0, "{secs}");
            }
        }
    }
    assert_eq!(fractions.first(), Some(&0.0));
    assert_eq!(fractions.last(), Some(&1.0));
    assert!(fractions.iter().all(|f| (0.0..=1.0).contains(f)));
    assert!(
        fractions.windows(2).all(|w| w[0] <= w[1]),
        "progress went back: {fractions:?}"
    );
    (fractions, lines)
}

/// A recording observer sees the solve's progress (in [0, 1], non-decreasing, ending with
/// `finished("solve")`), remaining-time estimates, and trace lines only when it asks for them;
/// the solution, and the progress, are the same whatever the observer.
#[test]
fn observer_sees_progress_and_only_requested_traces() {
    let mut s = cornell();
    s.radiosity.max_depth = 4;
    s.radiosity.shadow_rays = 8;
    let quiet = Recorder::default();
    let loud = Recorder::tracing();
    let a = solve(
        &s,
        &SolveOptions {
            observer: &quiet,
            ..SolveOptions::default()
        },
    )
    .expect("solve");
    let b = solve(
        &s,
        &SolveOptions {
            observer: &loud,
            ..SolveOptions::default()
        },
    )
    .expect("solve");
    let c = solve_quiet(&s);
    let (fa, la) = observed(&quiet.events());
    let (fb, lb) = observed(&loud.events());
    assert!(la.is_empty(), "traces without tracing: {la:?}");
    assert!(lb.len() >= 3, "{lb:?}");
    assert!(lb.iter().any(|l| l.starts_with("round 1:")), "{lb:?}");
    assert!(lb.iter().all(|l| !l.contains('\n')));
    // The fractions are priced from measured times, so two runs report different ones; each
    // run's are checked by `observed` (from 0, never decreasing, ending at 1).
    assert!(fa.len() > 3, "{fa:?}");
    assert!(fb.len() > 3, "{fb:?}");
    // The final gather reports its remaining time (after each of its chunks).
    let gathers = quiet
        .events()
        .iter()
        .filter(|e| matches!(e, Event::Remaining(p, _) if p == "round 1 gather"))
        .count();
    assert!(gathers >= 2, "{gathers} gather estimates");
    // Bit for bit (the file encoding leaves out only the wall-clock time).
    assert!(
        file::encode(&b) == file::encode(&c),
        "tracing changed the solution"
    );
    assert!(
        file::encode(&a) == file::encode(&c),
        "recording changed the solution"
    );
}

/// The memory guard stops a solve whose refinement would pass the limit, with an error that
/// carries the estimate; a limit the solve fits in changes nothing; and no leaf goes deeper than
/// the depth bound the budget's worst case assumes but by the dives it counts apart.
#[test]
fn memory_limit_stops_refinement_and_depth_bound_holds() {
    let (s, sol) = cornell_solution();
    let nodes: u64 = sol
        .polygons
        .iter()
        .map(|p| p.tree.nodes().len() as u64)
        .sum();
    let held = shoot::state_bytes(nodes, sol.stats.vertices);
    // Half of what the finished trees hold (pair tables come on top): the guard must trip.
    let opts = SolveOptions {
        memory_limit: held / 2,
        ..SolveOptions::default()
    };
    match solve(s, &opts) {
        Err(Error::Memory {
            estimate, limit, ..
        }) => {
            assert_eq!(limit, held / 2);
            assert!(estimate > limit);
        }
        other => panic!("expected a memory error, got {other:?}"),
    }
    // Room for everything gives the same solution as without a limit: checked by
    // `snapshots_change_nothing_and_come_after_every_phase`, which solves with a roomy limit.
    let min_size = shoot::min_element_size(s);
    for (r, p) in sol.polygons.iter().enumerate() {
        let deepest = p
            .tree
            .nodes()
            .iter()
            .map(|n| n.cell.level)
            .max()
            .unwrap_or(0);
        let start = s.radiosity.min_depth.max(2);
        let bound = shoot::depth_bound(s, r, min_size).max(start);
        // Past it only the leaves a shadow's edge crosses (the box's contact shadows), by at
        // most their levels and within the nodes the budget adds for dives.
        assert!(
            deepest <= bound + shoot::SHADOW_EDGE_LEVELS,
            "polygon {r}: depth {deepest} past the bound"
        );
        let past = p.tree.nodes().iter().filter(|n| n.cell.level > bound);
        assert!(past.count() as u64 <= shoot::DIVE_NODES, "polygon {r}");
    }
}

/// A solve that sends snapshots returns the solution it returns without them, bit for bit;
/// it sends one after the direct light and one per indirect round but the last, each a
/// solution of the scene (finite, non-negative samples on trees the final one refines
/// further), the first with only the emitters' light shot and the later ones lit more.
#[test]
fn snapshots_change_nothing_and_come_after_every_phase() {
    let (s, plain) = cornell_solution();
    let seen = std::sync::Mutex::new(Vec::new());
    let keep = |sol: Solution| seen.lock().unwrap().push(sol);
    // A memory limit with room for everything as well: neither the snapshots nor the limit's
    // checks change the solution.
    let opts = SolveOptions {
        snapshots: Some(&keep),
        memory_limit: 1 << 40,
        ..SolveOptions::default()
    };
    let sol = solve(s, &opts).expect("solve");
    assert_eq!(sol.polygons, plain.polygons);
    assert_eq!(sol.shooters, plain.shooters);
    let seen = seen.into_inner().unwrap();
    let rounds = plain.stats.refined_after.len();
    assert_eq!(
        seen.len(),
        rounds - 1,
        "one after the direct light, one per round but the last"
    );
    // The light on the box's faces: the face means times their areas, summed.
    let light = |sol: &Solution| -> f64 {
        crate::face_means(sol, s)
            .unwrap()
            .iter()
            .map(|f| f.total.x * f.area)
            .sum::<f64>()
    };
    for (k, snap) in seen.iter().enumerate() {
        assert_eq!(snap.scene_hash, plain.scene_hash);
        assert_eq!(snap.polygons.len(), plain.polygons.len());
        for p in &snap.polygons {
            assert_eq!(p.values.len(), p.keys.len());
            assert!(p
                .values
                .iter()
                .all(|v| v.is_finite() && v.min_element() >= 0.0));
        }
        let reflected = snap
            .shooters
            .iter()
            .filter(|sh| matches!(sh.kind, ShooterKind::Patch { .. }))
            .filter(|sh| sh.total != DVec3::ZERO)
            .count();
        if k == 0 {
            assert_eq!(
                reflected, 0,
                "the first snapshot holds the direct light only"
            );
        } else {
            assert!(
                light(snap) > light(&seen[k - 1]),
                "snapshot {k} is no brighter"
            );
        }
    }
    assert!(light(plain) > light(seen.last().unwrap()));
}
