//! Light that stops where geometry stops, through every method: no light crosses the line
//! where a wall stands on a floor or a box on a box (the loader cuts the receiver there, each
//! side reconstructed from its own samples), and a box's penumbra under an area light follows
//! the exact visible part of the light, clipped in the test itself. Run with `--nocapture` for
//! the numbers docs/accuracy.md quotes.

use std::path::Path;

use glam::{DVec2, DVec3};

use app::frames::render_frame;
use app::prepare::Prepared;
use base::method::{Filter, Method};
use engine::frame::FrameOptions;

/// Every method a user renders with: the PixelFlow path, both texture filters, the mesh and the
/// solution evaluated exactly per pixel.
const METHODS: [Method; 5] = [
    Method::Direct,
    Method::Texture(Filter::Bilinear),
    Method::Texture(Filter::Bicubic {
        b: 1.0 / 3.0,
        c: 1.0 / 3.0,
    }),
    Method::Mesh,
    Method::Reference,
];

/// Solves scene `text` and builds every model, as `render` does.
fn prepared(text: &str) -> Prepared {
    let path = Path::new("test.toml");
    crate::prepare_scene(path, scene::parse_scene(text, path).expect("scene"))
}

/// Luminance of each pixel of `method`'s image of `p` (its camera, `w` x `h`), row 0 on top.
fn image(p: &Prepared, method: Method, w: u32, h: u32) -> Vec<f64> {
    let f = render_frame(p, method, &p.scene.camera, &FrameOptions::new(w, h)).expect("renders");
    f.pixels
        .iter()
        .map(|c| 0.2126 * c.x as f64 + 0.7152 * c.y as f64 + 0.0722 * c.z as f64)
        .collect()
}

fn quad(material: &str, c: [[f64; 3]; 4]) -> String {
    let v: Vec<String> = c
        .iter()
        .map(|p| format!("[{}, {}, {}]", p[0], p[1], p[2]))
        .collect();
    format!(
        "[[polygons]]\nmaterial = \"{material}\"\nvertices = [{}]\n\n",
        v.join(", ")
    )
}

/// The faces of the box [lo, hi], facing out; without its bottom when `open_bottom`.
fn box_faces(material: &str, lo: [f64; 3], hi: [f64; 3], open_bottom: bool) -> String {
    let ([x0, y0, z0], [x1, y1, z1]) = (lo, hi);
    let mut faces = vec![
        [[x0, y1, z0], [x0, y1, z1], [x1, y1, z1], [x1, y1, z0]],
        [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],
        [[x1, y0, z0], [x0, y0, z0], [x0, y1, z0], [x1, y1, z0]],
        [[x1, y0, z1], [x1, y0, z0], [x1, y1, z0], [x1, y1, z1]],
        [[x0, y0, z0], [x0, y0, z1], [x0, y1, z1], [x0, y1, z0]],
    ];
    if !open_bottom {
        faces.push([[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]]);
    }
    faces.into_iter().map(|f| quad(material, f)).collect()
}

const MATERIALS: &str = r#"
[[materials]]
name = "white"
reflectance = [0.7, 0.7, 0.7]

[[materials]]
name = "black"
reflectance = [0.0, 0.0, 0.0]

[[materials]]
name = "grey"
reflectance = [0.5, 0.5, 0.5]

[[materials]]
name = "light"
reflectance = [0.0, 0.0, 0.0]
emission = [10.0, 10.0, 10.0]
"#;

/// What broke: a wall standing on a floor, lit from one side: the floor's C1 reconstruction
/// carried the light of the wall's lit foot across the line (0.44 of it on the floor just
/// behind the wall, above 1 % for 12 mm) where the solve itself had none. Seen from above at
/// 0.5 mm a pixel, every method's floor 1.25 mm or more behind the wall holds at most 1 % of
/// the light 0.75 mm in front of it (the light reaches the floor behind only after two bounces
/// off the dark side: measured 0 to float precision).
#[test]
fn no_method_carries_light_across_a_wall_standing_on_a_floor() {
    let wall_z = 0.1234;
    let mut text = format!(
        "[camera]\neye = [0.0, 3.0, {wall_z}]\nlook_at = [0.0, 0.0, {wall_z}]\nup = [0.0, 0.0, -1.0]\n\
         ortho_width = 0.1\northo_height = 0.1\n\n[image]\nwidth = 200\nheight = 200\n{MATERIALS}\n"
    );
    text += &quad(
        "white",
        [
            [-2.0, 0.0, 2.0],
            [2.0, 0.0, 2.0],
            [2.0, 0.0, -2.0],
            [-2.0, 0.0, -2.0],
        ],
    );
    let w = [
        [-1.0, 0.0, wall_z],
        [1.0, 0.0, wall_z],
        [1.0, 1.0, wall_z],
        [-1.0, 1.0, wall_z],
    ];
    text += &quad("white", w);
    text += &quad("white", [w[1], w[0], w[3], w[2]]);
    text += &quad(
        "light",
        [
            [-0.25, 1.5, 0.8],
            [0.25, 1.5, 0.8],
            [0.25, 1.5, 1.3],
            [-0.25, 1.5, 1.3],
        ],
    );
    let p = prepared(&text);
    assert!(
        !p.scene.contacts.lines.is_empty(),
        "the wall's foot is a contact line"
    );
    // Row 0 is at z = wall_z - 0.05 (the camera's up is -z): rows 0..=97 lie 1.25 mm or more
    // behind the wall, rows 101 and 102 0.75 and 1.25 mm in front.
    for method in METHODS {
        let img = image(&p, method, 200, 200);
        let row = |y: usize| &img[y * 200..(y + 1) * 200];
        let foot = row(101).iter().sum::<f64>() / 200.0;
        assert!(foot > 0.1, "{method:?}: the lit foot {foot}");
        let behind = (0..=97).flat_map(row).fold(0.0f64, |m, &v| m.max(v));
        eprintln!(
            "wall {method:?}: lit foot {foot:.4}, largest 1.25 mm or more behind {behind:.3e}"
        );
        assert!(
            behind <= 0.01 * foot,
            "{method:?}: {behind} behind the wall, {foot} at its lit foot"
        );
    }
}

/// A box standing on a box, lit from above beside it: the lower box's top is cut along the
/// upper box's foot (and the floor along the lower box's), and the light just outside the foot
/// comes from its own side's samples, not from the dark square under the upper box. Every
/// method's lower top 0.75-2.75 mm from the foot stays within 3 % of the exact evaluation there
/// (`reference`; measured: equal to rounding). Here the shadow edge at the foot already makes
/// the solver refine to its guard, so the uncut top measured the same: the test holds the lit
/// side's light through the cut (pieces, seams, textures, mesh), the wall above is the leak.
#[test]
fn a_box_on_a_box_keeps_its_light_on_its_own_side() {
    let mut text = format!(
        "[camera]\neye = [0.2, 3.0, 0.0]\nlook_at = [0.2, 0.0, 0.0]\nup = [0.0, 0.0, -1.0]\n\
         ortho_width = 0.02\northo_height = 0.02\n\n[image]\nwidth = 40\nheight = 40\n{MATERIALS}\n"
    );
    text += &quad(
        "white",
        [
            [-2.0, 0.0, 2.0],
            [2.0, 0.0, 2.0],
            [2.0, 0.0, -2.0],
            [-2.0, 0.0, -2.0],
        ],
    );
    text += &box_faces("white", [-0.5, 0.0, -0.5], [0.5, 0.4, 0.5], true);
    text += &box_faces("white", [-0.2, 0.4, -0.2], [0.2, 0.7, 0.2], true);
    text += &quad(
        "light",
        [
            [0.2, 1.5, -0.3],
            [0.8, 1.5, -0.3],
            [0.8, 1.5, 0.3],
            [0.2, 1.5, 0.3],
        ],
    );
    let p = prepared(&text);
    assert!(
        p.scene.contacts.lines.len() >= 8,
        "{:?}",
        p.scene.contacts.counts()
    );
    // The view is 20 mm wide at 0.5 mm a pixel, centred on the upper box's foot at x = 0.2:
    // columns 21..=25 lie 0.75-2.75 mm outside it on the lower box's lit top.
    let exact = image(&p, Method::Reference, 40, 40);
    for method in METHODS {
        let img = image(&p, method, 40, 40);
        let worst = (10..30)
            .flat_map(|y| (21..=25).map(move |x| y * 40 + x))
            .map(|k| (img[k] - exact[k]).abs() / exact[k])
            .fold(0.0f64, f64::max);
        eprintln!("box on box {method:?}: largest relative difference by the foot {worst:.2e}");
        for y in 10..30 {
            for x in 21..=25 {
                let (got, want) = (img[y * 40 + x], exact[y * 40 + x]);
                assert!(want > 0.1, "lit at ({x}, {y}): {want}");
                assert!(
                    (got - want).abs() <= 0.03 * want,
                    "{method:?} at ({x}, {y}): {got} against the exact {want}"
                );
            }
        }
    }
}

/// Lambert's form factor from `x` (normal `n`) to the planar polygon `poly`.
fn lambert(x: DVec3, n: DVec3, poly: &[DVec3]) -> f64 {
    let mut f = 0.0;
    for i in 0..poly.len() {
        let (a, b) = (
            (poly[i] - x).normalize(),
            (poly[(i + 1) % poly.len()] - x).normalize(),
        );
        let c = a.cross(b);
        let s = c.length();
        if s > 1e-300 {
            f += s.atan2(a.dot(b)) * c.dot(n) / s;
        }
    }
    f.abs() / (2.0 * std::f64::consts::PI)
}

/// The convex hull of `pts` (counter-clockwise), by gift wrapping.
fn hull(pts: &[DVec2]) -> Vec<DVec2> {
    let start = (0..pts.len())
        .min_by(|&a, &b| {
            pts[a]
                .x
                .total_cmp(&pts[b].x)
                .then(pts[a].y.total_cmp(&pts[b].y))
        })
        .unwrap();
    let mut out = vec![];
    let mut cur = start;
    loop {
        out.push(pts[cur]);
        let mut next = (cur + 1) % pts.len();
        for k in 0..pts.len() {
            let (a, b) = (pts[next] - pts[cur], pts[k] - pts[cur]);
            if a.perp_dot(b) < 0.0 || (a.perp_dot(b) == 0.0 && b.length() > a.length()) {
                next = k;
            }
        }
        cur = next;
        if cur == start || out.len() > pts.len() {
            return out;
        }
    }
}

/// `subject` clipped to the counter-clockwise convex `clip` (Sutherland-Hodgman).
fn clip(subject: &[DVec2], clip: &[DVec2]) -> Vec<DVec2> {
    let mut out = subject.to_vec();
    for i in 0..clip.len() {
        let (a, b) = (clip[i], clip[(i + 1) % clip.len()]);
        let side = |p: DVec2| (b - a).perp_dot(p - a);
        let input = std::mem::take(&mut out);
        for j in 0..input.len() {
            let (p, q) = (input[j], input[(j + 1) % input.len()]);
            let (sp, sq) = (side(p), side(q));
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                out.push(p + (q - p) * (sp / (sp - sq)));
            }
        }
    }
    out
}

/// The exact radiosity of the floor point `x` under the penumbra scene: rho E times the form
/// factor of the part of the light (the rectangle `light` at height `h`) the floating box
/// [lo, hi] leaves visible, the light less its part inside the box's shadow on the light's
/// plane (the convex hull of the box's corners projected from `x`), and the unshadowed value.
fn exact_floor(x: DVec3, light: [DVec2; 4], h: f64, lo: DVec3, hi: DVec3) -> (f64, f64) {
    let to3 = |p: DVec2| DVec3::new(p.x, h, p.y);
    let shadow: Vec<DVec2> = (0..8)
        .map(|k| {
            let c = DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            let p = x + (c - x) * ((h - x.y) / (c.y - x.y));
            DVec2::new(p.x, p.z)
        })
        .collect();
    // Both in the (x, z) plane counter-clockwise: the light's corners run that way.
    let shadow = hull(&shadow);
    let hidden = clip(&light, &shadow);
    let light3: Vec<DVec3> = light.iter().map(|&p| to3(p)).collect();
    let open = lambert(x, DVec3::Y, &light3);
    let covered = if hidden.len() >= 3 {
        lambert(
            x,
            DVec3::Y,
            &hidden.iter().map(|&p| to3(p)).collect::<Vec<_>>(),
        )
    } else {
        0.0
    };
    let (rho, e) = (0.5, 10.0);
    (rho * e * (open - covered), rho * e * open)
}

/// A black box floating under a rectangular light over a grey floor, nothing else reflecting:
/// the floor's radiosity is exactly rho E times the form factor of the part of the light each
/// point sees, clipped here against the box's shadow (Nishita and Nakamae's construction). It
/// was 8.2 % of the unshadowed value off in the penumbra, and the penumbra 7.6 % too narrow,
/// with shadow rays. Along a line across the penumbra every method stays within 1 % of the
/// unshadowed value, and the penumbra's width (from 10 % to 90 % of the unshadowed value)
/// within 2 % of the exact width.
#[test]
fn a_box_penumbra_under_an_area_light_matches_exact_clipping() {
    for drawn in penumbra(DVec2::new(0.3, 0.2)) {
        within_a_percent(drawn);
    }
}

/// The same box under a light a fifth the size: the penumbra (6.85 cm from 10 % to 90 %) is
/// three of the floor's smallest elements at the default depth wide, and its edges are kinks
/// the C1 patches round off over an element. What broke: the direct method read 4.2 % of the
/// unshadowed value off at the penumbra's edges (the mesh 7.0 %), and within 2 px of a
/// furnished room's shadow boundaries its error was 1.9 times that elsewhere. The leaves a
/// shadow's edge crosses now split two levels past the guards: the direct method and the
/// solution within 1 %, the penumbra's width within 2 %.
#[test]
fn a_narrow_penumbras_edges_are_followed_past_the_guards() {
    for drawn in penumbra(DVec2::new(0.06, 0.04)) {
        if matches!(drawn.0, Method::Direct | Method::Reference) {
            within_a_percent(drawn);
        }
    }
}

/// A method's penumbra (method, largest error relative to the unshadowed light, drawn width,
/// exact width): within 1 % of the unshadowed light everywhere, its width within 2 %.
fn within_a_percent((method, worst, w, exact): (Method, f64, f64, f64)) {
    assert!(
        worst <= 0.01,
        "{method:?}: {worst} of the unshadowed value off"
    );
    assert!(
        (w - exact).abs() <= 0.02 * exact,
        "{method:?}: penumbra {w} wide, exactly {exact}"
    );
}

/// The floating box's penumbra under a light of half-size `half` (x, z) at height 1.2, along
/// a row of 400 pixels from the box's edge across the penumbra: per method, the largest error
/// against the exact clipping relative to the unshadowed value, the drawn penumbra's width
/// (from 10 % to 90 % of the unshadowed value) and the exact width.
fn penumbra(half: DVec2) -> Vec<(Method, f64, f64, f64)> {
    let (lo, hi) = (DVec3::new(-0.4, 0.1, -0.4), DVec3::new(0.4, 0.5, 0.4));
    let h = 1.2;
    let light = [
        DVec2::new(-half.x, -half.y),
        DVec2::new(-half.x, half.y),
        DVec2::new(half.x, half.y),
        DVec2::new(half.x, -half.y),
    ];
    // Counter-clockwise in (x, z) as `clip` wants; `hull` returns the shadow the same way.
    let light = if (light[1] - light[0]).perp_dot(light[2] - light[1]) > 0.0 {
        light
    } else {
        [light[3], light[2], light[1], light[0]]
    };
    let mut text = format!(
        "[camera]\neye = [0.8, 3.0, 0.0]\nlook_at = [0.8, 0.0, 0.0]\nup = [0.0, 0.0, -1.0]\n\
         ortho_width = 0.8\northo_height = 0.008\n\n[image]\nwidth = 400\nheight = 4\n{MATERIALS}\n"
    );
    text += &quad(
        "grey",
        [
            [-1.5, 0.0, 1.5],
            [1.5, 0.0, 1.5],
            [1.5, 0.0, -1.5],
            [-1.5, 0.0, -1.5],
        ],
    );
    text += &box_faces("black", lo.to_array(), hi.to_array(), false);
    text += &quad(
        "light",
        [
            [-half.x, h, -half.y],
            [half.x, h, -half.y],
            [half.x, h, half.y],
            [-half.x, h, half.y],
        ],
    );
    let p = prepared(&text);
    // Pixel (i, j) sees the floor at x = 0.4 + (i + 0.5) 2 mm, z = -0.004 + (j + 0.5) 2 mm: from
    // the box's edge across the penumbra to x = 1.2.
    let at = |i: usize, j: usize| {
        DVec3::new(
            0.4 + (i as f64 + 0.5) * 0.002,
            0.0,
            -0.004 + (j as f64 + 0.5) * 0.002,
        )
    };
    let exact: Vec<(f64, f64)> = (0..400)
        .map(|i| exact_floor(at(i, 1), light, h, lo, hi))
        .collect();
    let width = |v: &dyn Fn(usize) -> f64| {
        let cross = |t: f64| {
            (1..400)
                .find(|&i| v(i) >= t * exact[i].1 && v(i - 1) < t * exact[i - 1].1)
                .map(|i| {
                    let (a, b) = (v(i - 1) - t * exact[i - 1].1, v(i) - t * exact[i].1);
                    at(i - 1, 1).x + 0.002 * (-a / (b - a))
                })
                .expect("the line crosses the penumbra")
        };
        cross(0.9) - cross(0.1)
    };
    let exact_width = width(&|i| exact[i].0);
    assert!(exact_width > 0.05, "the penumbra is seen: {exact_width}");
    let mut out = Vec::new();
    for method in METHODS {
        let img = image(&p, method, 400, 4);
        let mut worst = 0.0f64;
        for i in 0..400 {
            let (want, open) = exact[i];
            worst = worst.max((img[400 + i] - want).abs() / open);
        }
        let w = width(&|i| img[400 + i]);
        eprintln!(
            "penumbra of a {:.2} x {:.2} light, {method:?}: largest error {worst:.2e} of the \
             unshadowed value, width {w:.4} (exact {exact_width:.4})",
            2.0 * half.x,
            2.0 * half.y
        );
        out.push((method, worst, w, exact_width));
    }
    out
}

/// Luminance of every pixel of every method's image of `p` at `w` x `h`, reference first.
fn images(p: &Prepared, w: u32, h: u32) -> Vec<(Method, Vec<f64>)> {
    let mut out = vec![(Method::Reference, image(p, Method::Reference, w, h))];
    for method in METHODS.into_iter().filter(|m| *m != Method::Reference) {
        out.push((method, image(p, method, w, h)));
    }
    out
}

/// What broke: the Cornell box's lamp hangs 1 cm under the ceiling, so the ceiling above it is
/// dark and the step runs along the lamp's outline; a texel across the outline blended the two
/// sides, and the row where the ceiling shows through the gap was drawn 3-100x too bright (45
/// pixels within 3 px of the lamp more than 2x off the exact evaluation at 256 x 256, in both
/// texture methods). The ceiling is now cut along the outline: no method's pixel within 3 px
/// of the lamp is more than 2x off (below a floor of 1 % of the open ceiling's light there).
#[test]
fn no_method_blends_the_ceiling_across_the_cornell_lamps_outline() {
    let p = crate::shipped("cornell-box");
    let outlines: Vec<_> = p
        .scene
        .contacts
        .lines
        .iter()
        .filter(|l| matches!(l.kind, scene::contact::LineKind::Outline { .. }))
        .collect();
    assert_eq!(outlines.len(), 4, "{outlines:?}");
    let (w, h) = (256usize, 256usize);
    let all = images(p, w as u32, h as u32);
    let exact = &all[0].1;
    let lamp: Vec<bool> = exact.iter().map(|&v| v > 1.0).collect();
    let near: Vec<usize> = (0..w * h)
        .filter(|&k| {
            let (x, y) = ((k % w) as i64, (k / w) as i64);
            !lamp[k]
                && (-3..=3).any(|dy| {
                    (-3..=3).any(|dx| {
                        let (x, y) = (x + dx, y + dy);
                        (0..w as i64).contains(&x)
                            && (0..h as i64).contains(&y)
                            && lamp[y as usize * w + x as usize]
                    })
                })
        })
        .collect();
    assert!(near.len() > 200, "{} pixels by the lamp", near.len());
    let mut open: Vec<f64> = near.iter().map(|&k| exact[k]).collect();
    open.sort_by(f64::total_cmp);
    let floor = 0.01 * open[open.len() / 2];
    for (method, img) in &all[1..] {
        let off: Vec<(usize, f64, f64)> = near
            .iter()
            .filter(|&&k| img[k].max(exact[k]) > 2.0 * img[k].min(exact[k]) + floor)
            .map(|&k| (k, img[k], exact[k]))
            .collect();
        eprintln!(
            "cornell lamp {method:?}: {} of {} pixels more than 2x off",
            off.len(),
            near.len()
        );
        assert!(off.is_empty(), "{method:?}: {off:?}");
    }
}

/// The lit ceiling beside a lamp hung 1 cm under it, seen from below at 0.5 mm a pixel: the
/// light climbs from about half the open ceiling's at the outline (the lamp hides half the
/// room) to most of it within a few gaps (0.54 of the value 2 cm out at 0.75 mm, 0.90 at 1 cm),
/// a ramp narrower than the solver's smallest element (2.7 cm here). The solver follows it past
/// its guards down to leaves about a gap wide at the outline, as it follows a close light, and
/// a cubic across such a leaf stays within a few percent of the ramp: every method's ceiling
/// 0.75-19.75 mm from the outline within 5 % of the exact evaluation (measured 1.5-2.7 %;
/// 17-20 % when the solver stops at its guards).
#[test]
fn the_ceiling_beside_a_lamp_hung_under_it_follows_its_ramp() {
    let mut text = format!(
        "[camera]\neye = [0.25, 1.0, 0.0]\nlook_at = [0.25, 2.0, 0.0]\nup = [0.0, 0.0, -1.0]\n\
         ortho_width = 0.04\northo_height = 0.04\n\n[image]\nwidth = 80\nheight = 80\n{MATERIALS}\n"
    );
    // A closed 2 m room, faces inward: the room's walls are the ceiling's only light.
    let ([x0, y0, z0], [x1, y1, z1]) = ([-1.0, 0.0, -1.0], [1.0, 2.0, 1.0]);
    for f in [
        [[x0, y0, z0], [x0, y0, z1], [x1, y0, z1], [x1, y0, z0]],
        [[x0, y1, z0], [x1, y1, z0], [x1, y1, z1], [x0, y1, z1]],
        [[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0]],
        [[x0, y0, z1], [x0, y1, z1], [x1, y1, z1], [x1, y0, z1]],
        [[x0, y0, z0], [x0, y1, z0], [x0, y1, z1], [x0, y0, z1]],
        [[x1, y0, z0], [x1, y0, z1], [x1, y1, z1], [x1, y1, z0]],
    ] {
        text += &quad("white", f);
    }
    text += &quad(
        "light",
        [
            [-0.25, 1.99, -0.25],
            [0.25, 1.99, -0.25],
            [0.25, 1.99, 0.25],
            [-0.25, 1.99, 0.25],
        ],
    );
    let p = prepared(&text);
    let all = images(&p, 80, 80);
    let exact = &all[0].1;
    // The image's right is forward x up = -x: column c is at x = 0.27 - (c + 0.5) / 2000, so
    // the outline x = 0.25 lies between columns 39 and 40, the lamp fills 40..80 and columns
    // 0..=38 are the ceiling 0.75-19.75 mm beyond the outline.
    assert!(
        (20..60).all(|y| (40..80).all(|x| exact[y * 80 + x] > 9.0)),
        "the lamp"
    );
    let cols: Vec<usize> = (0..39).collect();
    for (method, img) in &all[1..] {
        let mut worst = 0.0f64;
        for y in 20..60 {
            for &x in &cols {
                let (got, want) = (img[y * 80 + x], exact[y * 80 + x]);
                assert!(want > 0.0, "lit at ({x}, {y})");
                worst = worst.max((got - want).abs() / want);
            }
        }
        eprintln!("lamp ramp {method:?}: largest relative difference {worst:.3}");
        assert!(worst <= 0.05, "{method:?}: {worst} off beside the lamp");
    }
}
