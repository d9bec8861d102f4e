//! The spot lights' part of a solution, exactly, at any point of any polygon: what lets the
//! reconstruction follow the sharp edges of their light (the rim of a cone, hard shadows)
//! instead of interpolating samples across them.
//!
//! A spot is a point source, so its light at a point is `rho * I(theta) * cos / r^2` times a
//! visibility of 0 or 1: one shadow ray, no integral. [`SpotParts::part`] is the very term the
//! solve's gather adds for a spot (same receiver point, same pair table and occluder candidates,
//! same ray), so a sample minus its spots' parts is the rest of its light to rounding, and the
//! lit/unlit answer at a sample is the solve's own. [`SpotParts::smooth`] is the same term
//! without its two cuts (the cone's rim and the occluders) at the polygon's plane point: a smooth
//! function whose derivatives the reconstruction takes, and which equals the part wherever the
//! spot lights a point (to the solve's 1e-6 pull of border points inside the polygon).
//!
//! Built from the solution's shooter totals (a spot's is 1 once it has shot) and pair tables
//! for the spots only, so it costs a BVH and one classification per spot and polygon, never the
//! patches' pairs that an [`Oracle`](crate::Oracle) needs.

use glam::DVec3;

use crate::transfer::Transfer;
use crate::{scene_hash, Solution};
use base::error::{Error, Result};
use scene::Scene;

/// The spot lights' exact part of a solution's radiosity at any point of any polygon: the term
/// the solve's gather adds for each spot, and its smooth continuation without the cone's cut and
/// the occluders.
pub struct SpotParts<'a> {
    tr: Transfer<'a>,
    /// Per spot, the total it shot (1 once shot, 0 if it never did).
    totals: Vec<DVec3>,
    /// Per polygon, the spots whose light can reach it, ascending, with the polygon's entry in
    /// the spot's pair table.
    reach: Vec<Vec<(u32, u32)>>,
}

impl<'a> SpotParts<'a> {
    /// The spots' parts of `sol` on `scene` (which must be the scene `sol` solves: another
    /// scene's solution is [`Error::Inconsistent`]).
    pub fn new(sol: &Solution, scene: &'a Scene) -> Result<SpotParts<'a>> {
        if sol.scene_hash != scene_hash(scene) {
            return Err(Error::inconsistent(
                "the solution was computed for another scene",
            ));
        }
        let spots = scene.spots.len();
        if sol.shooters.len() < spots {
            return Err(Error::inconsistent(format!(
                "the solution has {} shooters, fewer than the scene's {spots} spots",
                sol.shooters.len()
            )));
        }
        let mut tr = Transfer::new(scene);
        let totals: Vec<DVec3> = sol.shooters[..spots].iter().map(|s| s.total).collect();
        let mut reach = vec![Vec::new(); scene.polygons.len()];
        for (s, t) in totals.iter().enumerate() {
            if *t == DVec3::ZERO || scene.spots[s].intensity.max_element() <= 0.0 {
                continue;
            }
            tr.ensure_pairs(s);
            for (r, list) in reach.iter_mut().enumerate() {
                if scene.material_of(r).reflectance.max_element() <= 0.0 {
                    continue;
                }
                if let Some(i) = tr.pair_entry(s, r) {
                    list.push((s as u32, i as u32));
                }
            }
        }
        Ok(SpotParts { tr, totals, reach })
    }

    /// The spots whose light can reach polygon `polygon` (ascending; empty for an index out of
    /// range, a polygon that reflects nothing, or a scene without spots).
    pub fn reaching(&self, polygon: usize) -> Vec<u32> {
        self.reach
            .get(polygon)
            .map_or_else(Vec::new, |l| l.iter().map(|&(s, _)| s).collect())
    }

    /// Spot `spot`'s part of the radiosity of polygon `polygon` at (u, v): `Some(rho * I cos /
    /// r^2)` where it lights the point, `None` where it does not (outside its cone, or
    /// shadowed), also for a spot that cannot reach the polygon.
    pub fn part(&self, polygon: usize, spot: u32, u: f64, v: f64) -> Option<DVec3> {
        let list = self.reach.get(polygon)?;
        let k = list.binary_search_by_key(&spot, |&(s, _)| s).ok()?;
        let (s, i) = list[k];
        let g =
            self.totals[s as usize] * self.tr.transfer_at(s as usize, polygon, i as usize, u, v);
        if g == DVec3::ZERO {
            return None;
        }
        Some(self.tr.scene.material_of(polygon).reflectance * g)
    }

    /// Spot `spot`'s part of polygon `polygon`'s radiosity at the plane point of (u, v) (any
    /// real u, v: the polygon's bilinear map extended) without the cone's cut and without
    /// occluders: `rho * I max(cos theta, 0)^falloff * max(cos, 0) / r^2`. Zero for a spot that
    /// cannot reach the polygon.
    pub fn smooth(&self, polygon: usize, spot: u32, u: f64, v: f64) -> DVec3 {
        let Some(list) = self.reach.get(polygon) else {
            return DVec3::ZERO;
        };
        if list.binary_search_by_key(&spot, |&(s, _)| s).is_err() {
            return DVec3::ZERO;
        }
        let scene = self.tr.scene;
        let p = &scene.polygons[polygon];
        let l = &scene.spots[spot as usize];
        let x = p.point(u, v);
        let d = l.position - x;
        let r2 = d.length_squared();
        if r2 <= 0.0 {
            return DVec3::ZERO;
        }
        let dist = r2.sqrt();
        let cos = (p.shading_normal(x).dot(d) / dist).max(0.0);
        let c = (-l.direction.dot(d) / dist).max(0.0);
        let rho = scene.material_of(polygon).reflectance;
        rho * self.totals[spot as usize] * l.intensity * (c.powf(l.falloff) * cos / r2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_scenes::{spot_over_plane, two_spots};
    use crate::{solve, SolveOptions};

    /// Every sample of two-spots is its spots' parts plus the rest, and where a spot lights a
    /// sample its part equals the smooth term there (same formula; border points differ by the
    /// solve's 1e-6 inset only).
    #[test]
    fn parts_are_the_solve_own_terms() {
        let s = two_spots();
        let sol = solve(&s, &SolveOptions::default()).unwrap();
        let sp = SpotParts::new(&sol, &s).unwrap();
        let (mut lit, mut dark) = (0, 0);
        for (r, sq) in sol.polygons.iter().enumerate() {
            for (k, b) in sq.keys.iter().zip(&sq.values) {
                let mut sum = DVec3::ZERO;
                for spot in sp.reaching(r) {
                    match sp.part(r, spot, k.u(), k.v()) {
                        Some(p) => {
                            lit += 1;
                            let sm = sp.smooth(r, spot, k.u(), k.v());
                            assert!((p - sm).abs().max_element() <= 1e-4 * p.max_element());
                            sum += p;
                        }
                        None => dark += 1,
                    }
                }
                // The rest of the light is never negative beyond f32 rounding of the sample.
                let rest = b.as_dvec3() - sum;
                assert!(
                    rest.min_element() >= -1e-6 * b.max_element() as f64,
                    "{rest}"
                );
            }
        }
        assert!(lit > 100 && dark > 100, "lit {lit} dark {dark}");
    }

    /// A spot over a plane with nothing in between: its part is exactly the whole sample.
    #[test]
    fn a_lone_spot_is_the_whole_sample() {
        let s = spot_over_plane();
        let sol = solve(&s, &SolveOptions::default()).unwrap();
        let sp = SpotParts::new(&sol, &s).unwrap();
        let sq = &sol.polygons[0];
        for (k, b) in sq.keys.iter().zip(&sq.values) {
            let p = sp.part(0, 0, k.u(), k.v()).unwrap_or(DVec3::ZERO);
            let b = b.as_dvec3();
            assert!((p - b).abs().max_element() <= 1e-6 * b.max_element().max(1e-30));
        }
        assert!(sp.part(0, 1, 0.5, 0.5).is_none());
        assert!(sp.part(7, 0, 0.5, 0.5).is_none());
        assert_eq!(sp.smooth(7, 0, 0.5, 0.5), DVec3::ZERO);
    }
}
