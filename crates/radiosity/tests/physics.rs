//! The solver against physics: its per-polygon means (`radiosity::face_means`) against the
//! independent path tracer's (`truth::polygons`), on scenes where the bias the solver used to
//! have showed: one bounce between perpendicular surfaces, a box floating over a floor in a
//! closed room, and the Cornell box. A check passes when the solver is within the stated
//! fraction of the truth, plus three of the truth's standard errors (its noise).

use std::path::Path;

use glam::DVec3;

use base::progress::SILENT;
use fixtures::text::{box_faces, polygon};
use radiosity::{face_means, solve, SolveOptions};
use truth::TruthOptions;

/// The repository root (scenes), from this crate's directory.
const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

fn lum(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// A ratio solver / truth and the truth's relative standard error.
type Ratio = (f64, f64);

/// Per polygon: (solver total / truth total, the truth's relative standard error), and the
/// same for the indirect part (reflected light that bounced before), in luminance. A polygon
/// the loader cut along contact lines counts once, its pieces' means merged by their areas;
/// the truth traces `whole`, the same scene loaded without the cuts (the same surfaces).
fn ratios(scene: &scene::Scene, whole: &scene::Scene, samples: u64) -> Vec<(Ratio, Ratio)> {
    let sol = solve(scene, &SolveOptions::default()).expect("solves");
    ratios_of(scene, whole, &sol, samples)
}

/// The solver's mean radiosity `ours` over the truth's `t`, and the truth's relative standard
/// error, in luminance.
fn total_ratio(ours: DVec3, t: &truth::PolygonEstimate) -> Ratio {
    (
        lum(ours) / lum(t.radiosity),
        lum(t.radiosity_se) / lum(t.radiosity),
    )
}

/// Scene `text` as the solver loads it (cut along its contact lines), and whole.
fn parsed(text: &str, name: &str) -> (scene::Scene, scene::Scene) {
    let scene = scene::parse_scene(text, Path::new(name)).expect("scene");
    let whole = format!("{text}\n[radiosity]\ncut_contacts = false\n");
    let whole = scene::parse_scene(&whole, Path::new(name)).expect("the whole scene");
    (scene, whole)
}

/// The shipped scene at `rel` (from the repository's root) as the solver loads it, and whole.
fn loaded(rel: &str) -> (scene::Scene, scene::Scene) {
    let path = Path::new(REPO).join(rel);
    let scene = scene::load_scene(&path).expect("scene");
    let opts = scene::LoadOptions {
        overrides: vec![("radiosity.cut_contacts".into(), "false".into())],
        ..scene::LoadOptions::default()
    };
    (
        scene,
        scene::load_scene_with(&path, &opts).expect("the whole scene"),
    )
}

/// [`ratios`] of the solution `sol` of `scene`.
fn ratios_of(
    scene: &scene::Scene,
    whole: &scene::Scene,
    sol: &radiosity::Solution,
    samples: u64,
) -> Vec<(Ratio, Ratio)> {
    let ours = merged(scene, &face_means(sol, scene).expect("means"));
    let mut opts = TruthOptions::new(whole);
    opts.samples_per_polygon = samples;
    let truth = truth::polygons(whole, &opts, &SILENT).expect("traces");
    assert_eq!(ours.len(), truth.len());
    ours.iter()
        .zip(&truth)
        .map(|(o, t)| {
            let total = total_ratio(o.total, t);
            let ours_indirect = o.total - o.direct;
            let ind = if lum(t.indirect) > 0.0 {
                (
                    lum(ours_indirect) / lum(t.indirect),
                    lum(t.indirect_se) / lum(t.indirect),
                )
            } else {
                (1.0, 0.0)
            };
            (total, ind)
        })
        .collect()
}

/// The runs of pieces (indices after the cut) that each polygon before the cut became, in
/// order: one piece for a polygon the loader did not cut.
fn piece_groups(scene: &scene::Scene, pieces_len: usize) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut cuts = scene.contacts.pieces.iter().peekable();
    let mut r = 0;
    while r < pieces_len {
        let n = match cuts.peek() {
            Some(&&(orig, n)) if orig as usize == out.len() => {
                cuts.next();
                n as usize
            }
            _ => 1,
        };
        out.push(r..r + n);
        r += n;
    }
    out
}

/// The solver's face means with the pieces of each polygon cut along contact lines merged back
/// into one mean (area-weighted), in the order of the polygons before the cut.
fn merged(scene: &scene::Scene, means: &[radiosity::FaceMean]) -> Vec<radiosity::FaceMean> {
    piece_groups(scene, means.len())
        .into_iter()
        .map(|range| {
            let group = &means[range];
            let area: f64 = group.iter().map(|m| m.area).sum();
            let avg = |f: fn(&radiosity::FaceMean) -> DVec3| {
                group.iter().map(|m| f(m) * m.area).sum::<DVec3>() / area
            };
            radiosity::FaceMean {
                total: avg(|m| m.total),
                direct: avg(|m| m.direct),
                area,
            }
        })
        .collect()
}

fn check(name: &str, r: &[(Ratio, Ratio)], total_tol: f64, indirect_tol: f64) {
    for (i, ((t, tse), (ind, ise))) in r.iter().enumerate() {
        assert!(
            (t - 1.0).abs() <= total_tol + 3.0 * tse,
            "{name}: polygon {i}: solver / truth {t:.4} (truth's relative SE {tse:.4})"
        );
        assert!(
            (ind - 1.0).abs() <= indirect_tol + 3.0 * ise,
            "{name}: polygon {i}: indirect solver / truth {ind:.4} (SE {ise:.4})"
        );
    }
}

/// A floor, a wall along one of its edges and a lamp above: the wall's light on the floor and
/// the floor's on the wall are one bounce between perpendicular, adjacent surfaces. It was
/// 2.6-2.9 % low (reflecting patches taken as uniform, the unshot remainder never shot);
/// measured now within 0.3 %.
#[test]
fn one_bounce_between_a_floor_and_a_wall_matches_the_path_tracer() {
    let (scene, whole) = parsed(ONE_BOUNCE, "one-bounce.toml");
    let r = ratios(&scene, &whole, 65_536);
    check("one bounce", &r, 0.01, 0.015);
}

/// A closed room lit by its ceiling with a box floating 0.3 over the floor: the floor under
/// the box and the box's bottom light each other. Visibility weighted by area instead of the
/// kernel lost 1.5 % of the ceiling's light around the box; patches shooting more than they
/// turned out to reflect (unshot light clamped at zero) made the box's bottom 9 % too bright;
/// and while the rounds stopped on the unshot fraction of the emitted power alone, the
/// bottom's light, which depends on the floor right under it through the gap, read 3.3 %
/// bright (its patches ended 2-3 % off their own light). Measured now: every face within
/// 1.3 %, the bottom 1.002.
#[test]
fn a_box_over_a_floor_in_a_closed_room_matches_the_path_tracer() {
    let (scene, whole) = parsed(&closed_room(), "closed-room.toml");
    let r = ratios(&scene, &whole, 65_536);
    check("closed room", &r, 0.015, 0.02);
}

/// A closed 2 m room whose floor is black, lit by a lamp hanging under the middle of its
/// ceiling: the ceiling sees no lamp and no floor, so all its light is the walls' first
/// bounce, and the walls' light falls toward the ceiling (the lamp grazes them there). A far
/// part of a wall's patch counted as its mean deviation at its centre (no dipole) lost that
/// slope wherever the kernel follows it: the ceiling came out 2.5 % dark against the path
/// tracer, for any tolerance. Measured now: the ceiling within 0.6 %, the walls within
/// 0.4 %; the truth's standard error is 0.26 % with these samples, so the bound below
/// (0.5 % plus three standard errors, 1.3 % in all) holds the old error out.
#[test]
fn walls_lighting_a_ceiling_match_the_path_tracer() {
    let (scene, whole) = parsed(&wall_lit_ceiling(), "wall-lit.toml");
    let r = ratios(&scene, &whole, 262_144);
    // Polygons: floor, ceiling, four walls, lamp.
    check("ceiling", &r[1..2], 0.005, 0.005);
    check("walls", &r[2..6], 0.01, 0.01);
}

/// The room of [`walls_lighting_a_ceiling_match_the_path_tracer`]: a 2 m cube (inward faces)
/// with a black floor, white walls and ceiling (rho 0.7), and a 0.5 m lamp facing down 2 cm
/// under the ceiling's middle.
fn wall_lit_ceiling() -> String {
    let mut s = String::from(
        "[camera]\neye = [1.0, 1.0, 0.2]\nlook_at = [1.0, 1.0, 1.0]\nup = [0.0, 1.0, 0.0]\n\
         fov_y = 60.0\n\n[image]\nwidth = 32\nheight = 32\n\n\
         [[materials]]\nname = \"black\"\nreflectance = [0.0, 0.0, 0.0]\n\
         [[materials]]\nname = \"white\"\nreflectance = [0.7, 0.7, 0.7]\n\
         [[materials]]\nname = \"lamp\"\nreflectance = [0.0, 0.0, 0.0]\nemission = [10.0, 10.0, 10.0]\n\n",
    );
    for (k, f) in box_faces([0.0; 3], [2.0; 3], true).iter().enumerate() {
        let m = if k == 0 { "black" } else { "white" };
        s += &polygon(&format!("room{k}"), m, f);
    }
    let (lo, hi, z) = (0.75, 1.25, 1.98);
    s += &polygon(
        "lamp",
        "lamp",
        &[[lo, lo, z], [lo, hi, z], [hi, hi, z], [hi, lo, z]],
    );
    s
}

/// The Cornell box as shipped (its two repeated faces counted once, its floor cut along the
/// boxes' feet), against the path tracer on the same pieces: every lit piece within 1 % (plus
/// three of the truth's standard errors), and every face, its pieces merged, within 1 % and its
/// indirect light within 2 %. Measured at the scene's own settings against a million samples
/// per piece: 0.996-1.003 (docs/accuracy.md). The floor between the boxes read 1.031 while the
/// rounds stopped on the unshot fraction of the emitted power alone: the shapes a round gathered
/// with moved light its coarse shots had taken as uniform, and a wall patch seen through the
/// gap ended 5.5 % off its own light. Before exact visibility and the contact lines, the faces
/// read 0.961-1.045 over seeds 1-6. The seed places only shadow rays, which no transfer of this
/// scene casts now: the solution is the same at every seed.
#[test]
fn the_cornell_box_matches_the_path_tracer_piece_by_piece() {
    let (scene, _) = loaded("scenes/cornell-box.toml");
    let a = solve(&scene, &SolveOptions::default()).expect("solves");
    let ours = face_means(&a, &scene).expect("means");
    let mut opts = TruthOptions::new(&scene);
    opts.samples_per_polygon = 262_144;
    let truth = truth::polygons(&scene, &opts, &SILENT).expect("traces");
    let reflected = |t: &truth::PolygonEstimate| lum(t.radiosity - t.emission);
    let peak = truth.iter().map(reflected).fold(0.0, f64::max);
    let mut lit = 0;
    for (i, (o, t)) in ours.iter().zip(&truth).enumerate() {
        if t.emission != DVec3::ZERO || reflected(t) < 0.02 * peak {
            continue;
        }
        lit += 1;
        let (ratio, se) = total_ratio(o.total, t);
        assert!(
            (ratio - 1.0).abs() <= 0.01 + 3.0 * se,
            "cornell: piece {i}: solver / truth {ratio:.4} (truth's relative SE {se:.4})"
        );
    }
    assert!(lit >= 40, "only {lit} lit pieces");
    check("cornell", &merged_ratios(&scene, &ours, &truth), 0.01, 0.02);
    let mut other = scene.clone();
    other.radiosity.seed = 4;
    let b = solve(&other, &SolveOptions::default()).expect("solves");
    assert_eq!(a.polygons, b.polygons, "the seed moved a sample");
}

/// [`ratios_of`] from the truth traced on the cut pieces: the solver's and the truth's pieces
/// merged into whole faces by their areas (the truth's standard errors combined as
/// independent).
fn merged_ratios(
    scene: &scene::Scene,
    ours: &[radiosity::FaceMean],
    truth: &[truth::PolygonEstimate],
) -> Vec<(Ratio, Ratio)> {
    let whole = merged(scene, ours);
    piece_groups(scene, truth.len())
        .into_iter()
        .zip(&whole)
        .map(|(range, o)| {
            let group = &truth[range.clone()];
            let areas: Vec<f64> = ours[range].iter().map(|m| m.area).collect();
            let area: f64 = areas.iter().sum();
            let weighted = |f: fn(&truth::PolygonEstimate) -> DVec3| {
                group.iter().zip(&areas).map(move |(t, a)| f(t) * *a)
            };
            let mean = |f| weighted(f).sum::<DVec3>() / area;
            let se = |f| weighted(f).map(|x| x * x).sum::<DVec3>().map(f64::sqrt) / area;
            let (t, t_se) = (mean(|t| t.radiosity), se(|t| t.radiosity_se));
            let (i, i_se) = (mean(|t| t.indirect), se(|t| t.indirect_se));
            let ind = if lum(i) > 0.0 {
                (lum(o.total - o.direct) / lum(i), lum(i_se) / lum(i))
            } else {
                (1.0, 0.0)
            };
            ((lum(o.total) / lum(t), lum(t_se) / lum(t)), ind)
        })
        .collect()
}

/// A 1 m light panel 2 cm under the ceiling of a closed 3 m room, facing the ceiling (what a
/// tool that lights both faces of a panel leaves): the room gets only what escapes the gap,
/// from a ring of ceiling around the panel whose light falls from 3.5 to 1 within 2 cm. With
/// the ceiling whole, a shooter's cell across the panel's rim lent the hidden bright side's
/// light to the visible dim side: walls 18-22 % and the floor 28 % too bright (against a
/// million samples per face, docs/accuracy.md). Cut along the panel's outline, the walls read
/// 4.5-5.8 % and the floor 10 % bright at the default depth, the ring's patches shooting 9 %
/// more than they receive (`patch_power`); with that fixed, 0.3-1.5 % and 4.6 % against 16
/// million samples. The bounds are those rounded up (2 % and 5 %) plus three of the truth's
/// standard errors at these samples.
#[test]
fn a_panel_facing_a_close_ceiling_matches_the_path_tracer() {
    let (scene, whole) = loaded("scenes/hard/lamp-facing-ceiling.toml");
    let r = ratios(&scene, &whole, 262_144);
    // Polygons: floor, ceiling, four walls, panel.
    check("ceiling", &r[1..2], 0.01, 0.06);
    check("walls", &r[2..6], 0.02, 0.02);
    check("floor", &r[0..1], 0.05, 0.05);
}

/// A furnished room: a table (top and four legs) standing on the floor of a closed room, a
/// cabinet against a wall and a stool, lit by a ceiling panel hung 1 cm under the ceiling.
/// From the floor under the table and from the legs, a wall's patches are seen past the
/// table's top, its legs, the stool and the cabinet: more occluders than the exact visibility
/// query took (16), so shadow rays decided there, one fixed set per patch for every receiver,
/// and the error was one per face: a leg's face 4.6 % dark, the table's underside and the
/// floor under it 1-3 % (against a million samples per face, docs/accuracy.md). Every side of
/// the legs and every face of the table must be within 1 % plus three of the truth's standard
/// errors (about 0.6 % at these samples; measured within 1.0 % at a million).
#[test]
fn a_table_and_its_legs_match_the_path_tracer() {
    let (scene, whole) = parsed(&furnished_room(), "furnished.toml");
    let sol = solve(&scene, &SolveOptions::default()).expect("solves");
    let r = ratios_of(&scene, &whole, &sol, 65_536);
    let name = |i: usize| whole.objects[whole.polygons[i].object as usize].as_str();
    let table: Vec<_> = (0..r.len())
        .filter(|&i| {
            name(i).starts_with("table") || (name(i).starts_with("leg") && !name(i).contains("top"))
        })
        .map(|i| r[i])
        .collect();
    assert_eq!(
        table.len(),
        6 + 4 * 4,
        "the table's faces and the legs' sides"
    );
    check("table", &table, 0.01, 0.01);
}

/// [`a_table_and_its_legs_match_the_path_tracer`]'s scene (y up): a 4 x 2.7 x 3 m room.
fn furnished_room() -> String {
    let mut s = String::from(
        "[camera]\neye = [3.6, 1.6, 2.7]\nlook_at = [1.6, 0.6, 1.0]\nup = [0.0, 1.0, 0.0]\n\
         fov_y = 60.0\n\n[image]\nwidth = 32\nheight = 32\n\n\
         [[materials]]\nname = \"wall\"\nreflectance = [0.7, 0.7, 0.7]\n\
         [[materials]]\nname = \"floor\"\nreflectance = [0.5, 0.45, 0.4]\n\
         [[materials]]\nname = \"wood\"\nreflectance = [0.6, 0.4, 0.25]\n\
         [[materials]]\nname = \"lamp\"\nreflectance = [0.0, 0.0, 0.0]\nemission = [12.0, 12.0, 12.0]\n\n",
    );
    // box_faces' order: z = lo, z = hi, x = lo, x = hi, y = lo (the floor), y = hi.
    for (k, f) in box_faces([0.0; 3], [4.0, 2.7, 3.0], true)
        .iter()
        .enumerate()
    {
        s += &polygon(
            &format!("room{k}"),
            if k == 4 { "floor" } else { "wall" },
            f,
        );
    }
    // The panel: the downward face of a thin box 1 cm under the ceiling.
    s += &polygon(
        "lamp",
        "lamp",
        &box_faces([1.6, 2.68, 1.1], [2.4, 2.69, 1.9], false)[4],
    );
    let mut solid = |name: &str, lo: [f64; 3], hi: [f64; 3], faces: &[usize]| {
        let f = box_faces(lo, hi, false);
        for &k in faces {
            s += &polygon(&format!("{name}{k}"), "wood", &f[k]);
        }
    };
    let (x0, z0, x1, z1) = (1.3, 1.0, 2.5, 1.8);
    solid("table", [x0, 0.72, z0], [x1, 0.77, z1], &[0, 1, 2, 3, 4, 5]);
    for (i, (x, z)) in [
        (x0 + 0.05, z0 + 0.05),
        (x1 - 0.1, z0 + 0.05),
        (x0 + 0.05, z1 - 0.1),
        (x1 - 0.1, z1 - 0.1),
    ]
    .into_iter()
    .enumerate()
    {
        // Its top touches the table's underside, its bottom the floor.
        solid(
            &format!("leg{i}_"),
            [x, 0.0, z],
            [x + 0.05, 0.72, z + 0.05],
            &[0, 1, 2, 3],
        );
        solid(
            &format!("leg{i}_top"),
            [x, 0.0, z],
            [x + 0.05, 0.72, z + 0.05],
            &[5],
        );
    }
    solid("cabinet", [0.3, 0.0, 0.0], [1.1, 1.2, 0.45], &[1, 2, 3, 5]);
    solid("stool", [2.8, 0.0, 2.0], [3.2, 0.45, 2.4], &[0, 1, 2, 3, 5]);
    s
}

const ONE_BOUNCE: &str = r#"
[camera]
eye = [3.0, 1.0, 2.0]
look_at = [1.0, 1.0, 0.5]
up = [0.0, 0.0, 1.0]
fov_y = 60.0

[image]
width = 32
height = 32

[[materials]]
name = "floor"
reflectance = [0.5, 0.5, 0.5]
[[materials]]
name = "wall"
reflectance = [0.8, 0.8, 0.8]
[[materials]]
name = "lamp"
reflectance = [0.0, 0.0, 0.0]
emission = [10.0, 10.0, 10.0]

[[polygons]]
name = "floor"
material = "floor"
vertices = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0]]

[[polygons]]
name = "wall"
material = "wall"
vertices = [[0.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 2.0, 2.0], [0.0, 0.0, 2.0]]

[[polygons]]
name = "lamp"
material = "lamp"
vertices = [[0.75, 0.75, 1.5], [0.75, 1.25, 1.5], [1.25, 1.25, 1.5], [1.25, 0.75, 1.5]]
"#;

/// The closed room: a 2 m cube (inward faces, rho 0.5 0.6 0.7) whose ceiling emits 3 2 1, and
/// a box (outward faces, rho 0.8) from (0.5, 0.6, 0.3) to (1.2, 1.3, 1.0). Polygon 6 is the
/// box's bottom.
fn closed_room() -> String {
    let mut s = String::from(
        "[camera]\neye = [1.0, 1.0, 0.2]\nlook_at = [1.0, 1.0, 1.0]\nup = [0.0, 1.0, 0.0]\n\
         fov_y = 60.0\n\n[image]\nwidth = 32\nheight = 32\n\n\
         [[materials]]\nname = \"walls\"\nreflectance = [0.5, 0.6, 0.7]\n\
         [[materials]]\nname = \"ceiling\"\nreflectance = [0.5, 0.6, 0.7]\nemission = [3.0, 2.0, 1.0]\n\
         [[materials]]\nname = \"box\"\nreflectance = [0.8, 0.8, 0.8]\n\n",
    );
    let room = box_faces([0.0; 3], [2.0; 3], true);
    for (k, f) in room.iter().enumerate() {
        let m = if k == 1 { "ceiling" } else { "walls" };
        s += &polygon(&format!("room{k}"), m, f);
    }
    for (k, f) in box_faces([0.5, 0.6, 0.3], [1.2, 1.3, 1.0], false)
        .iter()
        .enumerate()
    {
        s += &polygon(&format!("box{k}"), "box", f);
    }
    s
}

/// A closed 2 m room (white walls, rho 0.7) lit by a lamp under its ceiling, with a 1 m light
/// panel (rho 0.5, E = 3) 1e-9 in front of the right wall, facing it, and `panel_e` its
/// emission.
fn panel_facing_a_wall(panel_e: f64) -> String {
    panel_by_a_wall(panel_e, 1e-9, true)
}

/// [`panel_facing_a_wall`] with the panel `gap` in front of the wall, facing the wall or the
/// room.
fn panel_by_a_wall(panel_e: f64, gap: f64, facing_wall: bool) -> String {
    let mut s = format!(
        "[camera]\neye = [1.0, 1.0, 0.2]\nlook_at = [1.0, 1.0, 1.0]\nup = [0.0, 1.0, 0.0]\n\
         fov_y = 60.0\n\n[image]\nwidth = 32\nheight = 32\n\n\
         [[materials]]\nname = \"white\"\nreflectance = [0.7, 0.7, 0.7]\n\
         [[materials]]\nname = \"lamp\"\nreflectance = [0.0, 0.0, 0.0]\nemission = [10.0, 10.0, 10.0]\n\
         [[materials]]\nname = \"panel\"\nreflectance = [0.5, 0.5, 0.5]\n\
         emission = [{panel_e}, {panel_e}, {panel_e}]\n\n"
    );
    for (k, f) in box_faces([0.0; 3], [2.0; 3], true).iter().enumerate() {
        s += &polygon(&format!("room{k}"), "white", f);
    }
    let (lo, hi, y) = (0.75, 1.25, 1.98);
    s += &polygon(
        "lamp",
        "lamp",
        &[[lo, y, lo], [hi, y, lo], [hi, y, hi], [lo, y, hi]],
    );
    let x = 2.0 - gap;
    let mut c = [[x, 0.5, 0.5], [x, 1.5, 0.5], [x, 1.5, 1.5], [x, 0.5, 1.5]];
    if !facing_wall {
        c.reverse();
    }
    s += &polygon("panel", "panel", &c);
    s
}

/// The face means of `scene`'s solution and its energy account.
fn means_and_account(scene: &scene::Scene) -> (Vec<radiosity::FaceMean>, radiosity::EnergyAccount) {
    let sol = solve(scene, &SolveOptions::default()).expect("solves");
    (face_means(&sol, scene).expect("means"), sol.stats.energy)
}

/// What broke: the same panel turned to face the room (a lamp mounted flush on a wall) lay
/// over the wall closer than rays resolve, so the wall under it went on receiving and
/// reflecting the room's light through it, and the room's light that lands there was
/// reflected twice: the account read 14 % of the emitted light created; snapped into the
/// wall's plane (gap 0), the panel and the wall both took the light of the overlap and the
/// account read 19.5 % created. The piece of the wall under it is now buried (the panel's back
/// takes its light; in the wall's plane the emitter lies on top): it is dark, and the room
/// reads as with the panel 1 mm off the wall, where the rays resolve the gap.
#[test]
fn a_lamp_a_hair_in_front_of_a_wall_lights_the_room_once() {
    let path = Path::new("lamp-on-wall.toml");
    let off = scene::parse_scene(&panel_by_a_wall(3.0, 1e-3, false), path).expect("scene");
    let off_means = means_and_account(&off).0;
    for gap in [1e-9, 0.0] {
        lamp_on_wall_lights_the_room_once(gap, &off, &off_means);
    }
}

/// [`a_lamp_a_hair_in_front_of_a_wall_lights_the_room_once`] at `gap`, against the panel 1 mm
/// off the wall (`off`, its face means `off_means`).
fn lamp_on_wall_lights_the_room_once(
    gap: f64,
    off: &scene::Scene,
    off_means: &[radiosity::FaceMean],
) {
    let path = Path::new("lamp-on-wall.toml");
    let flush = scene::parse_scene(&panel_by_a_wall(3.0, gap, false), path).expect("scene");
    assert_eq!(
        flush.polygons.len(),
        off.polygons.len(),
        "gap {gap}: the same cut"
    );
    let (means, e) = means_and_account(&flush);
    assert!(
        e.error().abs() <= radiosity::ENERGY_ERROR_WARN,
        "gap {gap}: {e:?}"
    );
    let sealed = flush.seals();
    let under: Vec<usize> = (0..means.len())
        .filter(|&i| sealed.is_sealed(i as u32))
        .collect();
    assert_eq!(
        under.len(),
        1,
        "gap {gap}: the wall under the panel: {sealed:?}"
    );
    for (i, (m, o)) in means.iter().zip(off_means).enumerate() {
        let (b, d) = (lum(m.total), lum(o.total));
        if i == under[0] {
            assert!(
                b == 0.0 && d < 1e-3,
                "gap {gap}: under the panel: {b} flush, {d} 1 mm off"
            );
        } else {
            assert!(
                (b / d - 1.0).abs() <= 0.01,
                "gap {gap}: polygon {i}: {b} flush, {d} 1 mm off"
            );
        }
    }
}

/// What broke: a light panel 1e-9 in front of a wall and facing it (a lamp mounted with its
/// winding reversed) is closer than any ray's blind zone. The wall under it received its light,
/// but also lit the room through the panel, and the panel's light counted as escaping the
/// scene as well: the energy account read 156 % of the emitted light created in the hard test
/// room. The two are now sealed (`scene::seal`): they exchange light only with each other, in
/// the solver and in the path tracer alike. Checked here: the pair against its closed form
/// (the wall under the panel sees only the panel and the panel only it, so B_w = rho_w E /
/// (1 - rho_w rho_p) and B_p = E + rho_p B_w), the room unchanged when the panel is dark, every
/// face against the path tracer of the same scene, and the energy account.
#[test]
fn a_panel_facing_a_wall_a_hair_away_keeps_its_light_between_them() {
    let path = Path::new("panel-facing-wall.toml");
    let scene = scene::parse_scene(&panel_facing_a_wall(3.0), path).expect("scene");
    let dark = scene::parse_scene(&panel_facing_a_wall(0.0), path).expect("scene");
    let (means, e) = means_and_account(&scene);
    assert!(e.error().abs() <= radiosity::ENERGY_ERROR_WARN, "{e:?}");
    let dark_means = means_and_account(&dark).0;
    let sealed = scene.seals();
    let (rho_w, rho_p, em) = (0.7, 0.5, 3.0);
    let b_w = rho_w * em / (1.0 - rho_w * rho_p);
    let mut pair = 0;
    for (i, m) in means.iter().enumerate() {
        let b = lum(m.total);
        if !sealed.is_sealed(i as u32) {
            let d = lum(dark_means[i].total);
            assert!(
                (b / d - 1.0).abs() <= 0.01,
                "polygon {i}: {b} lit, {d} dark"
            );
            continue;
        }
        pair += 1;
        let want = if scene.material_of(i).is_emitter() {
            em + rho_p * b_w
        } else {
            b_w
        };
        assert!(
            (b / want - 1.0).abs() <= 0.01,
            "sealed {i}: {b}, closed form {want}"
        );
    }
    assert_eq!(pair, 2, "the panel and the wall under it: {sealed:?}");
    let mut opts = TruthOptions::new(&scene);
    opts.samples_per_polygon = 16_384;
    let truth = truth::polygons(&scene, &opts, &SILENT).expect("traces");
    for (i, (m, t)) in means.iter().zip(&truth).enumerate() {
        let (r, se) = total_ratio(m.total, t);
        assert!(
            (r - 1.0).abs() <= 0.02 + 3.0 * se,
            "polygon {i}: {r} (SE {se})"
        );
    }
}
