use super::*;
use proptest::prelude::*;

fn quad(c: [[f64; 3]; 4]) -> Polygon {
    Polygon::quad(c.map(DVec3::from_array), 0, 0).expect("quad")
}

/// A 4 x 4 floor at y = 0 facing up (u along +x, v along -z).
fn floor() -> Polygon {
    quad([
        [-2.0, 0.0, 2.0],
        [2.0, 0.0, 2.0],
        [2.0, 0.0, -2.0],
        [-2.0, 0.0, -2.0],
    ])
}

/// The four sides of a box of footprint corners `f` (counter-clockwise seen from above) and
/// height `h`, standing on y = 0, facing out.
fn box_sides(f: [[f64; 2]; 4], h: f64) -> Vec<Polygon> {
    (0..4)
        .map(|i| {
            let (a, b) = (f[i], f[(i + 1) % 4]);
            // Seen from outside, counter-clockwise: bottom a, bottom b, top b, top a reversed
            // so the normal points out of a footprint wound counter-clockwise from above.
            quad([
                [b[0], 0.0, b[1]],
                [a[0], 0.0, a[1]],
                [a[0], h, a[1]],
                [b[0], h, b[1]],
            ])
        })
        .collect()
}

fn area(ps: &[Polygon]) -> f64 {
    ps.iter().map(|p| p.area).sum()
}

/// Whether `p` lies (within `tol`) on one side of the line through `a` and `b` in the floor.
fn one_side(p: &Polygon, a: DVec3, b: DVec3, tol: f64) -> bool {
    let d = b - a;
    let s: Vec<f64> = p
        .vertices()
        .iter()
        .map(|v| DVec3::Y.dot(d.cross(*v - a)) / d.length())
        .collect();
    s.iter().all(|&x| x >= -tol) || s.iter().all(|&x| x <= tol)
}

/// A 2 m wall standing on a 4 m floor: the floor is cut along the wall's foot and across it at
/// the wall's two ends (so that the parts of the line the wall does not stand on are edges of
/// their own), into a 3 x 2 grid of quads that tile it.
#[test]
fn a_wall_on_a_floor_cuts_it_along_its_foot() {
    let wall = quad([
        [-1.0, 0.0, 0.3],
        [1.0, 0.0, 0.3],
        [1.0, 1.0, 0.3],
        [-1.0, 1.0, 0.3],
    ]);
    let mut polys = vec![floor(), wall];
    let lines = find(&polys, &Stacking::default());
    assert_eq!(lines.len(), 1, "{lines:?}");
    let l = lines[0].clone();
    assert_eq!((l.receiver, l.by), (0, 1));
    assert!((l.a.z - 0.3).abs() < 1e-12 && (l.b.z - 0.3).abs() < 1e-12);
    assert!(((l.b - l.a).length() - 2.0).abs() < 1e-12);
    let mut origins: Vec<u32> = vec![10, 11];
    let cuts = cut(&mut polys, &mut origins, lines);
    assert_eq!(polys.len(), 7);
    assert_eq!(origins, vec![10, 10, 10, 10, 10, 10, 11]);
    assert_eq!(cuts.pieces, vec![(0, 6)]);
    assert!((area(&polys[..6]) - 16.0).abs() < 1e-9);
    for p in &polys[..6] {
        assert_eq!(p.shape, crate::Shape::Quad);
        assert!(one_side(p, l.a, l.b, 1e-12));
        let across = |x: f64| one_side(p, DVec3::new(x, 0.0, 0.0), DVec3::new(x, 0.0, 1.0), 1e-12);
        assert!(across(-1.0) && across(1.0));
        assert!((p.normal - DVec3::Y).length() < 1e-12);
    }
}

#[test]
fn a_wall_on_the_floor_border_or_floating_cuts_nothing() {
    let on_border = quad([
        [-2.0, 0.0, -2.0],
        [2.0, 0.0, -2.0],
        [2.0, 1.0, -2.0],
        [-2.0, 1.0, -2.0],
    ]);
    let floating = quad([
        [-1.0, 0.1, 0.3],
        [1.0, 0.1, 0.3],
        [1.0, 1.0, 0.3],
        [-1.0, 1.0, 0.3],
    ]);
    let below = quad([
        [-1.0, -1.0, 0.3],
        [1.0, -1.0, 0.3],
        [1.0, 0.0, 0.3],
        [-1.0, 0.0, 0.3],
    ]);
    for other in [on_border, floating, below] {
        assert!(find(&[floor(), other.clone()], &Stacking::default())
            .iter()
            .all(|l| l.receiver != 0));
    }
}

/// A wall passing through the floor cuts the floor, and the floor cuts the wall (its part
/// below the floor is a piece of its own).
#[test]
fn crossing_polygons_cut_each_other() {
    let wall = quad([
        [-1.0, -0.5, 0.3],
        [1.0, -0.5, 0.3],
        [1.0, 1.0, 0.3],
        [-1.0, 1.0, 0.3],
    ]);
    let mut polys = vec![floor(), wall];
    let lines = find(&polys, &Stacking::default());
    let receivers: Vec<u32> = lines.iter().map(|l| l.receiver).collect();
    assert_eq!(receivers, vec![0, 1]);
    let mut origins: Vec<()> = Vec::new();
    let cuts = cut(&mut polys, &mut origins, lines);
    // The floor: along the wall and across at its ends (3 x 2); the wall: along the floor,
    // which crosses it from end to end (2).
    assert_eq!(cuts.pieces, vec![(0, 6), (1, 2)]);
    assert!(origins.is_empty());
    // The wall's two pieces: one above the floor, one below, split at y = 0.
    let wall_pieces = &polys[6..];
    assert!((area(wall_pieces) - 3.0).abs() < 1e-9);
    assert!(wall_pieces
        .iter()
        .all(|p| p.vertices().iter().all(|v| v.y >= -1e-12)
            || p.vertices().iter().all(|v| v.y <= 1e-12)));
}

/// An axis-aligned box on the floor: its four sides' lines cut the floor in a 3 x 3 grid of
/// quads (the arrangement of the lines), which tile it; the middle one is under the box.
#[test]
fn a_box_cuts_a_floor_into_a_grid() {
    let f = [[-0.5, 0.5], [0.5, 0.5], [0.5, -0.5], [-0.5, -0.5]];
    let mut polys = vec![floor()];
    polys.extend(box_sides(f, 1.0));
    let lines = find(&polys, &Stacking::default());
    let on_floor: Vec<&ContactLine> = lines.iter().filter(|l| l.receiver == 0).collect();
    assert_eq!(on_floor.len(), 4);
    let mut origins: Vec<()> = Vec::new();
    let cuts = cut(&mut polys, &mut origins, lines);
    assert_eq!(cuts.pieces, vec![(0, 9)]);
    let pieces = &polys[..9];
    assert!(pieces.iter().all(|p| p.shape == crate::Shape::Quad));
    assert!((area(pieces) - 16.0).abs() < 1e-9);
    for l in cuts.lines.iter().filter(|l| l.receiver == 0) {
        assert!(pieces.iter().all(|p| one_side(p, l.a, l.b, 1e-9)));
    }
}

prop_compose! {
    /// A box of random size, place and turn standing on the floor, inside it.
    fn standing_box()(cx in -1.2f64..1.2, cz in -1.2f64..1.2, w in 0.1f64..0.7, d in 0.1f64..0.7,
                      turn in 0.0f64..1.57) -> [[f64; 2]; 4] {
        let (s, c) = turn.sin_cos();
        let at = |x: f64, z: f64| [cx + c * x - s * z, cz + s * x + c * z];
        // Counter-clockwise seen from above (+y): x then -z.
        [at(-w, d), at(w, d), at(w, -d), at(-w, -d)]
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Random boxes on a floor: the floor's pieces tile it (their areas add up to its area),
    /// every piece is a convex triangle or quad in the floor's plane facing up, and no piece
    /// straddles a contact line's line (every piece lies on one side of it, within the snap).
    #[test]
    fn pieces_tile_the_floor_and_straddle_no_contact_line(
        boxes in prop::collection::vec(standing_box(), 1..4),
    ) {
        let mut polys = vec![floor()];
        for b in &boxes {
            polys.extend(box_sides(*b, 0.5));
        }
        let lines = find(&polys, &Stacking::default());
        let floor_lines: Vec<ContactLine> = lines.iter().filter(|l| l.receiver == 0).cloned().collect();
        prop_assert_eq!(floor_lines.len(), 4 * boxes.len());
        let mut origins: Vec<()> = Vec::new();
        let cuts = cut(&mut polys, &mut origins, lines);
        let n = cuts.pieces.iter().find(|(p, _)| *p == 0).map_or(1, |(_, n)| *n as usize);
        let pieces = &polys[..n];
        prop_assert!((area(pieces) - 16.0).abs() < 1e-9 * 16.0, "area {}", area(pieces));
        for p in pieces {
            prop_assert!((p.normal - DVec3::Y).length() < 1e-9);
            prop_assert!(p.vertices().iter().all(|v| v.y.abs() < 1e-12));
            for l in &floor_lines {
                prop_assert!(one_side(p, l.a, l.b, SNAP * 6.0));
            }
        }
    }
}

/// A 4 x 4 ceiling at height 2 facing down, and a lamp of half-side `w` hung `gap` under its
/// middle, facing down; everything times `scale`.
fn ceiling_and_lamp(gap: f64, w: f64, scale: f64) -> Vec<Polygon> {
    let s = |c: [[f64; 3]; 4]| quad(c.map(|v| v.map(|x| x * scale)));
    let y = 2.0 - gap;
    vec![
        s([
            [-2.0, 2.0, -2.0],
            [2.0, 2.0, -2.0],
            [2.0, 2.0, 2.0],
            [-2.0, 2.0, 2.0],
        ]),
        s([[-w, y, -w], [w, y, -w], [w, y, w], [-w, y, w]]),
    ]
}

/// What broke: a lamp hung 1 cm under a ceiling left the ceiling whole, so a texel of its
/// texture straddled the lamp's outline and blended the dark ceiling above the lamp with the
/// lit ceiling beside it. The ceiling is cut along the lamp's outline (four lines, each
/// carrying the gap), into a 3 x 3 grid whose middle piece lies over the lamp, at any scale.
#[test]
fn a_lamp_hung_under_a_ceiling_cuts_it_along_its_outline() {
    for scale in [1e-3, 1.0, 1e3] {
        let mut polys = ceiling_and_lamp(0.01, 0.5, scale);
        assert!((polys[0].normal + DVec3::Y).length() < 1e-12);
        let lines = find(&polys, &Stacking::default());
        assert_eq!(lines.len(), 4, "{lines:?}");
        for l in &lines {
            assert_eq!((l.receiver, l.by), (0, 1));
            let LineKind::Outline { gap } = l.kind else {
                panic!("{l:?} is not an outline");
            };
            assert!((gap - 0.01 * scale).abs() <= 1e-9 * scale, "{gap}");
            assert!(((l.b - l.a).length() - scale).abs() <= 1e-9 * scale);
            assert!(l.a.y == 2.0 * scale && l.b.y == 2.0 * scale);
        }
        let mut origins: Vec<()> = Vec::new();
        let cuts = cut(&mut polys, &mut origins, lines);
        assert_eq!(cuts.pieces, vec![(0, 9)]);
        assert_eq!(cuts.outlines(), 4);
        let pieces = &polys[..9];
        assert!((area(pieces) - 16.0 * scale * scale).abs() < 1e-9 * 16.0 * scale * scale);
        // Exactly one piece lies over the lamp, and it is the lamp's footprint.
        let over: Vec<&Polygon> = pieces
            .iter()
            .filter(|p| {
                p.vertices().iter().all(|v| {
                    v.x.abs() <= 0.5 * scale * (1.0 + 1e-9)
                        && v.z.abs() <= 0.5 * scale * (1.0 + 1e-9)
                })
            })
            .collect();
        assert_eq!(over.len(), 1);
        assert!((over[0].area - scale * scale).abs() < 1e-9 * scale * scale);
        for p in pieces {
            assert!((p.normal + DVec3::Y).length() < 1e-12);
            for l in &cuts.lines {
                assert!(one_side(p, l.a, l.b, 1e-9 * scale));
            }
        }
        assert!(cuts
            .note()
            .is_some_and(|n| n.contains("4 of them sides of polygons lying close")));
    }
}

/// Only a polygon close in front of the receiver cuts it: a lamp farther than
/// [`OUTLINE_GAP`] of its half-width (a 1 m lamp 6.5 cm down, the limit 6.25 cm), one above the
/// ceiling (behind it), and one tilted through the ceiling's plane draw no outline; 6 cm down
/// does.
#[test]
fn only_a_polygon_close_in_front_draws_its_outline() {
    let outlines = |polys: &[Polygon]| {
        find(polys, &Stacking::default())
            .iter()
            .filter(|l| matches!(l.kind, LineKind::Outline { .. }))
            .count()
    };
    assert_eq!(outlines(&ceiling_and_lamp(0.06, 0.5, 1.0)), 4);
    assert_eq!(outlines(&ceiling_and_lamp(0.065, 0.5, 1.0)), 0);
    assert_eq!(outlines(&ceiling_and_lamp(-0.01, 0.5, 1.0)), 0);
    let mut tilted = ceiling_and_lamp(0.01, 0.5, 1.0);
    tilted[1] = quad([
        [-0.5, 2.01, -0.5],
        [0.5, 2.01, -0.5],
        [0.5, 1.97, 0.5],
        [-0.5, 1.97, 0.5],
    ]);
    assert_eq!(outlines(&tilted), 0);
}

/// What a modelling tool exports for a round ceiling light: a fan of thin triangles 1 cm under
/// the ceiling. Each triangle alone is too thin for the gap to count as close (half-width 5 cm
/// for a 0.3 m disc of 16), and its spokes are no step in the light; the fan is one sheet, and
/// the ceiling is cut along the 16 sides of its rim only. A 2 m lamp split into two triangles
/// cuts along its 4 sides, not its diagonal.
#[test]
fn a_lamp_of_triangles_cuts_along_its_rim_only() {
    let (r, y, n) = (0.3, 1.99, 16);
    let rim: Vec<DVec3> = (0..n)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / n as f64;
            DVec3::new(r * t.cos(), y, r * t.sin())
        })
        .collect();
    let mut polys = vec![ceiling_and_lamp(0.01, 0.5, 1.0).remove(0)];
    for k in 0..n {
        let c = DVec3::new(0.0, y, 0.0);
        polys.push(Polygon::triangle([c, rim[k], rim[(k + 1) % n]], 0, 0).expect("triangle"));
    }
    assert!(
        (polys[1].normal + DVec3::Y).length() < 1e-12,
        "the fan faces down"
    );
    let lines = find(&polys, &Stacking::default());
    assert_eq!(lines.len(), n, "{lines:?}");
    for l in &lines {
        assert_eq!(l.receiver, 0);
        // On the rim: both ends at the disc's radius (a spoke would reach the centre).
        for e in [l.a, l.b] {
            assert!((DVec2::new(e.x, e.z).length() - r).abs() < 1e-9, "{l:?}");
        }
    }
    let mut two = vec![polys[0].clone()];
    let c = [
        DVec3::new(-1.0, y, -1.0),
        DVec3::new(1.0, y, -1.0),
        DVec3::new(1.0, y, 1.0),
        DVec3::new(-1.0, y, 1.0),
    ];
    for t in [[c[0], c[3], c[2]], [c[0], c[2], c[1]]] {
        two.push(Polygon::triangle(t, 0, 0).expect("triangle"));
    }
    let lines = find(&two, &Stacking::default());
    assert_eq!(lines.len(), 4, "{lines:?}");
    assert!(lines.iter().all(|l| (l.a.x.abs() - 1.0).abs() < 1e-12
        && (l.b.x.abs() - 1.0).abs() < 1e-12
        || (l.a.z.abs() - 1.0).abs() < 1e-12 && (l.b.z.abs() - 1.0).abs() < 1e-12));
}

prop_compose! {
    /// A rectangular lamp of random size, place and turn, hung under the ceiling of
    /// [`ceiling_and_lamp`] by a random share of the outline gap, facing down; and that share.
    fn hung_lamp()(cx in -1.0f64..1.0, cz in -1.0f64..1.0, w in 0.05f64..0.6, d in 0.05f64..0.6,
                   turn in 0.0f64..1.57, share in 0.02f64..0.95) -> (Polygon, f64) {
        let (s, c) = turn.sin_cos();
        // Half-width of a w x d rectangle (sides 2w, 2d): 2 * area / perimeter.
        let half = 2.0 * (4.0 * w * d) / (4.0 * (w + d));
        let y = 2.0 - share * OUTLINE_GAP * half;
        let at = |x: f64, z: f64| [cx + c * x - s * z, y, cz + s * x + c * z];
        // Clockwise seen from above: facing down.
        (quad([at(-w, -d), at(w, -d), at(w, d), at(-w, d)]), share)
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// A random lamp closer than the outline gap cuts the ceiling along its four sides, with
    /// their gap; the pieces tile the ceiling, face down with it, and none straddles a side.
    #[test]
    fn a_hung_lamp_cuts_the_ceiling_along_its_sides((lamp, share) in hung_lamp()) {
        prop_assert!((lamp.normal + DVec3::Y).length() < 1e-9);
        let gap = 2.0 - lamp.corners[0].y;
        let mut polys = vec![ceiling_and_lamp(0.01, 0.5, 1.0).remove(0), lamp];
        let lines = find(&polys, &Stacking::default());
        prop_assert_eq!(lines.len(), 4, "share {}: {:?}", share, lines);
        for l in &lines {
            prop_assert_eq!((l.receiver, l.by), (0, 1));
            let LineKind::Outline { gap: g } = l.kind else {
                panic!("{l:?} is not an outline");
            };
            prop_assert!((g - gap).abs() <= 1e-12, "{} against {}", g, gap);
        }
        let mut origins: Vec<()> = Vec::new();
        let cuts = cut(&mut polys, &mut origins, lines);
        let n = cuts.pieces.first().map_or(1, |(_, n)| *n as usize);
        let pieces = &polys[..n];
        prop_assert!((area(pieces) - 16.0).abs() < 1e-9 * 16.0, "area {}", area(pieces));
        for p in pieces {
            prop_assert!((p.normal + DVec3::Y).length() < 1e-9);
            for l in &cuts.lines {
                prop_assert!(one_side(p, l.a, l.b, SNAP * 6.0));
            }
        }
    }
}

/// What broke: a light panel a hair (1e-9) in front of a ceiling lay within the plane
/// tolerance, so the ceiling was left whole, and the ceiling above the panel, which sees only
/// the panel (facing it) or nothing (its back), was one surface with the ceiling beside it. A
/// face in front of a receiver cuts it however close (down to rounding), either way it faces,
/// so that the piece under it can be sealed (`crate::seal`); one in its plane cuts it only if
/// it faces its way and lies on top (`crate::coincident::Stacking`).
#[test]
fn a_panel_facing_a_ceiling_a_hair_away_cuts_it_along_its_outline() {
    let outlines = |polys: &[Polygon]| {
        find(polys, &Stacking::default())
            .iter()
            .filter(|l| matches!(l.kind, LineKind::Outline { .. }))
            .count()
    };
    let facing = |gap: f64| {
        let mut polys = ceiling_and_lamp(gap, 0.5, 1.0);
        let mut c = polys[1].corners;
        c.reverse();
        polys[1] = Polygon::quad(c, 0, 0).expect("quad");
        assert!((polys[1].normal - DVec3::Y).length() < 1e-12);
        polys
    };
    for gap in [1e-9, 1e-7, 1e-5, 0.01] {
        assert_eq!(outlines(&facing(gap)), 4, "facing, gap {gap}");
    }
    assert_eq!(outlines(&facing(0.0)), 0, "in the ceiling's plane");
    assert_eq!(
        outlines(&ceiling_and_lamp(1e-9, 0.5, 1.0)),
        4,
        "its back to it"
    );
    assert_eq!(
        outlines(&ceiling_and_lamp(0.0, 0.5, 1.0)),
        0,
        "its back, in the plane"
    );
    // In the ceiling's plane, facing its way, and on top of it (listed later, one object): it
    // cuts the ceiling as it does a hair under it; facing the ceiling, it is back to back.
    let stacked = |polys: &[Polygon]| {
        find(polys, &Stacking::of(polys, &[]))
            .iter()
            .filter(|l| matches!(l.kind, LineKind::Outline { .. }) && l.receiver == 0)
            .count()
    };
    assert_eq!(
        stacked(&ceiling_and_lamp(0.0, 0.5, 1.0)),
        4,
        "on top, in the plane"
    );
    assert_eq!(stacked(&facing(0.0)), 0, "facing it, in the plane");
}
