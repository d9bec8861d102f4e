//! The solver: the state of one solve and its phases, in the order of the parent module's
//! documentation (set-up, direct pass, refinement, indirect rounds of shooting, gathering and
//! refining again), with the memory guard, the progress and the trace lines.

use std::sync::atomic::Ordering;
use std::time::Instant;

use glam::DVec3;

mod settle;

#[cfg(test)]
pub(crate) use settle::without_settling;

use super::energy;
use super::eta::{Eta, Phase};
use super::poly::{Light, PatchLayout, Poly};
use super::refine::refine;
use super::shapes;
use super::shot::{shoot, CoarseCache, Plan, PlanTransfers, Shot};
use super::unshot::{self, Unshot};
use super::{elapsed_ms, memory_error, state_bytes, Outcome, MAX_ROUNDS, SHOOT_MARGIN};
use crate::transfer::seen::SeenCache;
use crate::transfer::shape::PatchShape;
use crate::transfer::{PairClass, ShooterKind, Transfer};
use base::error::{human_bytes, Result};
use base::progress::Stage;
use base::quadtree::VertexKey;
use scene::Scene;

/// The final gather runs in this many chunks, so that its remaining time can be reported.
const GATHER_CHUNKS: usize = 64;

/// One solve in progress. It borrows the caller's scene, transfer and stage for `'a`; `'t` and
/// `'o` are the transfer's and the stage's own.
pub(super) struct Solver<'a, 't, 'o> {
    scene: &'a Scene,
    /// Shooters, pair tables and the light transfer (built on `scene`).
    tr: &'a mut Transfer<'t>,
    /// Where progress, remaining time and trace lines go.
    stage: &'a mut Stage<'o>,
    /// Whether the observer wants trace lines.
    tracing: bool,
    /// Bytes the solve's state may hold ([`state_bytes`] plus the pair tables).
    memory_limit: u64,
    /// The scene's `radiosity.convergence`: the unshot fraction the solve stops below.
    convergence: f64,
    /// Where each polygon's patches are among the shooters.
    patches: PatchLayout,
    /// Per polygon: its tree, vertices and G, coarse receivers and leaves.
    polys: Vec<Poly>,
    /// Per shooter: the total radiosity it has shot (the history every gather sums).
    totals: Vec<DVec3>,
    /// Per shooter: what it has still to shoot; the next shooter.
    unshot: Unshot,
    /// Per patch shooter: the integral of G over the patch from the fine leaves (light that
    /// reached every vertex: direct shots, gathers) ...
    fine: Vec<DVec3>,
    /// ... from the coarse cells (light shot to the coarse receivers since the last full
    /// gather) ...
    coarse: Vec<DVec3>,
    /// ... and from the fine leaves of the light shots concentrated on less than a coarse cell
    /// (see `shot`) since the last full gather.
    concentrated: Vec<DVec3>,
    /// The patches' coarse transfers, kept from their first shot.
    cache: CoarseCache,
    /// What the gathers saw of the geometry at each point, for the next gather there.
    seen: SeenCache,
    /// Shots taken, and the most the solve takes.
    shots: u64,
    max_shots: u64,
    /// Indirect rounds started.
    round: u32,
    /// The unshot fraction the solve is judged on: after the latest indirect shot or
    /// refinement pass.
    fraction: f64,
    /// The unshot fraction after every shot.
    history: Vec<f64>,
    /// Shots taken before each refinement pass.
    refined_after: Vec<u64>,
    /// Leaves refined to a guard with the error test failing, over all passes.
    guard_stops: crate::GuardStops,
    /// Wall-clock times of the trace lines.
    clock: Clock,
    /// The remaining-time estimate while shooting.
    eta: Eta,
    /// Receives the state of the solve at the end of each phase but the last
    /// ([`super::run`]).
    snapshot: Option<&'a dyn Fn(Outcome)>,
}

/// Wall-clock times for the trace lines.
struct Clock {
    start: Instant,
    /// Seconds spent building pair tables, and shooting, in the indirect rounds.
    pairs: f64,
    shots: f64,
}

impl<'a, 't, 'o> Solver<'a, 't, 'o> {
    /// Set-up: every polygon uniformly subdivided, spots and emitters holding their emission.
    /// `tr` must be built on `scene`; at most `cache_entries` coarse transfers are cached.
    pub(super) fn new(
        scene: &'a Scene,
        tr: &'a mut Transfer<'t>,
        stage: &'a mut Stage<'o>,
        cache_entries: usize,
        memory_limit: u64,
    ) -> Self {
        let patches = PatchLayout::of(scene);
        let polys = (0..scene.polygons.len())
            .map(|i| Poly::new(scene, i, &patches))
            .collect();
        let ns = tr.shooters.len();
        let unshot = Unshot::new(tr);
        Solver {
            scene,
            tracing: stage.observer().tracing(),
            tr,
            stage,
            memory_limit,
            convergence: scene.radiosity.convergence,
            patches,
            polys,
            totals: vec![DVec3::ZERO; ns],
            unshot,
            fine: vec![DVec3::ZERO; ns],
            coarse: vec![DVec3::ZERO; ns],
            concentrated: vec![DVec3::ZERO; ns],
            // The cache is a speed-up, not part of the result: it takes at most an eighth of
            // the memory limit, and its bytes count against the limit in every refinement.
            cache: CoarseCache::new(ns, cache_entries.min(cache_budget(memory_limit))),
            // Also a speed-up only: it gives its room back when the solve's state needs it.
            seen: SeenCache::new(scene.polygons.len(), ns, seen_budget(memory_limit)),
            shots: 0,
            max_shots: 100 * ns as u64 + 100,
            round: 0,
            fraction: 0.0,
            history: Vec::new(),
            refined_after: Vec::new(),
            guard_stops: crate::GuardStops::default(),
            clock: Clock {
                start: Instant::now(),
                pairs: 0.0,
                shots: 0.0,
            },
            eta: Eta::new(),
            snapshot: None,
        }
    }

    /// The same solver keeping at most `bytes` of what its gathers see ([`SeenCache`]).
    #[cfg(test)]
    pub(super) fn with_seen_budget(mut self, bytes: u64) -> Self {
        self.seen = SeenCache::new(self.polys.len(), self.totals.len(), bytes);
        self
    }

    /// Sends the state of the solve to `snapshot` at the end of each phase but the last.
    pub(super) fn with_snapshots(mut self, snapshot: Option<&'a dyn Fn(Outcome)>) -> Self {
        self.snapshot = snapshot;
        self
    }

    /// Runs every phase. With nothing emitted, only the direct pass runs (it shoots nothing) and
    /// every G stays zero.
    pub(super) fn solve(mut self) -> Result<Outcome> {
        self.direct_pass();
        if self.unshot.emitted > 0.0 {
            self.enter(Phase::Refine);
            self.refine_and_reestimate()?;
            self.send_snapshot();
            self.trace(|sv| {
                format!(
                    "direct + refine {:.0} ms, shots {}, vertices {}, unshot {}",
                    elapsed_ms(sv.clock.start),
                    sv.shots,
                    sv.vertices(),
                    percent(sv.fraction)
                )
            });
            while self.round < MAX_ROUNDS {
                if self.indirect_round()? {
                    break;
                }
            }
            if self.round == 0 {
                // No indirect round (MAX_ROUNDS is 0): the samples still come from a full gather.
                self.gather();
            }
        }
        // Every phase has run: whatever the estimate said, the work is done.
        self.stage.advance(1.0);
        Ok(self.into_outcome())
    }

    /// The direct pass's order: spots in id order, then emitters by decreasing power (ties by id).
    fn direct_order(&self) -> Vec<usize> {
        let tr = &*self.tr;
        let is_spot = |s: usize| matches!(tr.shooters[s].kind, ShooterKind::Spot { .. });
        let power = |s: usize| unshot::power(tr, s, self.unshot.radiosity[s]);
        let mut direct: Vec<usize> = (0..tr.shooters.len())
            .filter(|&s| !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. }))
            .collect();
        direct.sort_by(|&a, &b| {
            let (spot_a, spot_b) = (is_spot(a), is_spot(b));
            spot_b
                .cmp(&spot_a)
                .then_with(|| {
                    if spot_a && spot_b {
                        std::cmp::Ordering::Equal
                    } else {
                        power(b).total_cmp(&power(a))
                    }
                })
                .then(a.cmp(&b))
        });
        direct
    }

    /// Direct pass: every spot and emitter with power shoots its emission once, to every vertex.
    fn direct_pass(&mut self) {
        for s in self.direct_order() {
            let db = self.unshot.radiosity[s];
            if unshot::power(self.tr, s, db) <= 0.0 {
                continue;
            }
            let t = Instant::now();
            let shot = shoot(self.tr, &mut self.polys, s, db, None);
            self.eta.transfers(shot.points, t.elapsed().as_secs_f64());
            self.record_shot(s, db, &shot, false);
        }
    }

    /// One indirect round: patches shoot to the coarse receivers until the estimate is below
    /// [`SHOOT_MARGIN`] times the convergence threshold, then every vertex gathers, the trees
    /// are refined and the unshot light is re-estimated. Returns whether the solve is done
    /// (converged, or out of shots).
    fn indirect_round(&mut self) -> Result<bool> {
        self.round += 1;
        self.enter(Phase::Shooting);
        let target = SHOOT_MARGIN * self.convergence;
        while self.fraction >= target && self.shots < self.max_shots {
            let Some(s) = self.unshot.next() else { break };
            self.indirect_shot(s, target)?;
        }
        self.trace_shooting_done();
        self.flush_unshot()?;
        self.gather();
        self.trace(|sv| {
            format!(
                "  gather done {:.0} ms, kept {}",
                elapsed_ms(sv.clock.start),
                human_bytes(sv.seen.bytes())
            )
        });
        self.enter(Phase::Refine);
        let splits = self.refine_and_reestimate()?;
        self.trace(|sv| {
            format!(
                "round {}: {:.0} ms, shots {}, splits {splits}, vertices {}, unshot {}, rays {}",
                sv.round,
                elapsed_ms(sv.clock.start),
                sv.shots,
                sv.vertices(),
                percent(sv.fraction),
                sv.rays()
            )
        });
        if self.shots >= self.max_shots {
            return Ok(true);
        }
        // The shapes the samples imply; if they differ from those gathered with, another
        // round gathers with them (the last round's shapes are the ones kept).
        let new = shapes::measure(self.scene, self.tr, &self.polys, &self.patches);
        let change = shapes::change(self.tr, &new, &self.totals);
        let floor = settle::dark_floor(&new, &self.totals);
        let (moved, relative) = self.moved_patches(&new, floor);
        self.trace(|_| {
            format!(
                "  shapes change {change:.4}, where the light falls {relative:.4} ({} patches)",
                moved.len()
            )
        });
        self.trace(|sv| {
            format!(
                "  largest residual of a patch {} of its light",
                percent_of(sv.residual())
            )
        });
        let converged = self.fraction < self.convergence;
        let settled = change <= shapes::SHAPE_CHANGE;
        if converged && settled && self.residual() <= self.convergence {
            return Ok(true);
        }
        if self.round < MAX_ROUNDS {
            // Once the light has converged only the shapes are left: settle them where they
            // have not (before, the shots still move the light the shapes describe). A round
            // asked for by the residuals alone takes the shapes as measured: they have
            // settled, and settling again where they move a little costs more than the round.
            let new = if converged && !settled && !moved.is_empty() && settle::enabled() {
                let (new, passes) = self.settle_shapes(new, &moved, floor);
                self.trace(|_| {
                    format!(
                        "  shapes settled on {} patches in {passes} passes",
                        moved.len()
                    )
                });
                new
            } else {
                new
            };
            self.install_shapes(new);
            self.send_snapshot();
        }
        Ok(false)
    }

    /// The luminance of the light every polygon reflects, rho G integrated over it, summed.
    fn reflected_power(&self) -> f64 {
        self.polys
            .iter()
            .filter(|p| p.reflects())
            .map(|p| super::lum(p.rho * p.integral()))
            .sum()
    }

    /// The state of the solve as an outcome (its energy account empty), to the snapshot
    /// receiver if there is one. Every vertex holds G from the history so far.
    fn send_snapshot(&self) {
        let Some(send) = self.snapshot else { return };
        send(Outcome {
            energy: crate::EnergyAccount::default(),
            trees: self
                .polys
                .iter()
                .map(|p| (p.tree.clone(), p.keys.clone(), p.g.clone()))
                .collect(),
            totals: self.totals.clone(),
            kinds: self.tr.shooters.iter().map(|s| s.kind).collect(),
            shapes: (0..self.tr.shooters.len())
                .map(|s| self.tr.shape(s).cloned())
                .collect(),
            shots: self.shots,
            history: self.history.clone(),
            unshot: self.fraction,
            emitted: self.unshot.emitted,
            refined_after: self.refined_after.clone(),
            guard_stops: crate::GuardStops {
                reflected_power: self.reflected_power(),
                ..self.guard_stops
            },
            rays: self.rays(),
        });
    }

    /// Gathers from now on distribute each patch's light by its shape in `new`, and so do the
    /// shots; what a patch has shot so far is delivered again with its new shape (the change
    /// added to its receivers' coarse and concentrated light) where the shape changed by more
    /// than a share of [`shapes::SHAPE_CHANGE`]: otherwise the next gather finds the light a
    /// new shape moves (a ceiling's bright spot over a panel 2 cm below it, growing with every
    /// round as more bounces reach it) as unshot light the round's shots never estimated, and
    /// the rounds end far from converged.
    fn install_shapes(&mut self, new: Vec<(usize, Option<PatchShape>)>) {
        let brightest = shapes::brightest_patch(&new, &self.totals);
        let changed: Vec<(usize, Option<PatchShape>)> = new
            .into_iter()
            .filter(|(s, shape)| self.tr.shape(*s) != shape.as_ref())
            .collect();
        let moved: Vec<usize> = changed
            .iter()
            .filter(|(s, shape)| {
                self.totals[*s] != DVec3::ZERO
                    && shapes::shooter_change(self.tr, *s, shape.as_ref(), &self.totals, brightest)
                        > shapes::RESHOOT_SHARE * shapes::SHAPE_CHANGE
            })
            .map(|(s, _)| *s)
            .collect();
        let (tr, polys) = (&*self.tr, &self.polys);
        let before: Vec<(Plan, PlanTransfers)> = moved
            .iter()
            .map(|&s| {
                let plan = Plan::of(tr, polys, s);
                let t = plan.transfers(tr, polys, s);
                (plan, t)
            })
            .collect();
        for (s, shape) in changed {
            // The coarse transfers of a concentrated patch follow its shape
            // (`Transfer::coarse_transfer`).
            if shapes::concentrates(self.tr.shape(s)) || shapes::concentrates(shape.as_ref()) {
                self.cache.forget(s);
            }
            self.tr.set_shape(s, shape);
        }
        for (&s, (plan, old)) in moved.iter().zip(before) {
            let new = plan.transfers(self.tr, &self.polys, s);
            let shot = plan.add_change(&mut self.polys, self.totals[s], old, new);
            let concentrated = shot.concentrated.iter().map(|&r| r as usize);
            self.integrate(concentrated, Light::Concentrated);
            let touched = || shot.touched.iter().map(|&r| r as usize);
            self.integrate(touched(), Light::Coarse);
            self.reestimate(touched());
        }
        self.fraction = self.unshot.fraction();
    }

    /// Patch `s` shoots its unshot radiosity to the coarse receivers (building its pair table
    /// on its first shot); `target` is the round's, for the remaining-time estimate.
    fn indirect_shot(&mut self, s: usize, target: f64) -> Result<()> {
        let db = self.unshot.radiosity[s];
        if self.shots.is_multiple_of(100) {
            self.trace(|sv| {
                format!(
                    "  shot {}: {:.0} ms, unshot {}, rays {}",
                    sv.shots,
                    elapsed_ms(sv.clock.start),
                    percent(sv.fraction),
                    sv.rays()
                )
            });
        }
        let shot_start = Instant::now();
        let first_shot = self.tr.pairs[s].is_none();
        if first_shot {
            self.add_pair_table(s)?;
        }
        self.clock.pairs += shot_start.elapsed().as_secs_f64();
        let transfer_start = Instant::now();
        // Whether this shot computes its transfers (a cached one only adds them): only computed
        // ones tell what a gather's transfer costs.
        let computes = !self.cache.holds(s);
        let shot = shoot(self.tr, &mut self.polys, s, db, Some(&mut self.cache));
        let dt = transfer_start.elapsed().as_secs_f64();
        self.clock.shots += dt;
        if computes {
            self.eta.transfers(shot.points, dt);
        }
        self.fraction = self.record_shot(s, db, &shot, true);
        self.eta
            .shot_took(first_shot, shot_start.elapsed().as_secs_f64());
        let now = self.clock.start.elapsed().as_secs_f64();
        let counts = self.eta.due(now).then(|| {
            let unpaired = self.unpaired();
            (unpaired, self.expected_gather_transfers(unpaired))
        });
        self.eta
            .shot(self.stage, now, (self.fraction, target), counts);
        Ok(())
    }

    /// After shooter `s` shot `db` (to the fine vertices, or to the coarse receivers and the
    /// fine vertices of the polygons it concentrates on if `coarse`): its total and unshot
    /// radiosity, the integrals and unshot radiosity of the patches of the polygons it reached,
    /// the history and the progress. Returns the unshot fraction.
    fn record_shot(&mut self, s: usize, db: DVec3, shot: &Shot, coarse: bool) -> f64 {
        self.totals[s] += db;
        self.unshot.set(self.tr, s, DVec3::ZERO);
        self.shots += 1;
        let touched = || shot.touched.iter().map(|&r| r as usize);
        if coarse {
            self.integrate(touched(), Light::Coarse);
            let concentrated = shot.concentrated.iter().map(|&r| r as usize);
            self.integrate(concentrated, Light::Concentrated);
        } else {
            self.integrate(touched(), Light::Fine);
        }
        self.reestimate(touched());
        let fraction = self.unshot.fraction();
        self.history.push(fraction);
        fraction
    }

    /// Builds shooter `s`'s pair table, then applies the memory guard again (the trees do not
    /// grow while shooting, the pair tables do).
    fn add_pair_table(&mut self, s: usize) -> Result<()> {
        self.tr.ensure_pairs(s);
        let (nodes, vertices) = (self.nodes(), self.vertices());
        let pair_bytes = self.tr.pair_bytes();
        let need = state_bytes(nodes, vertices as u64).saturating_add(pair_bytes);
        self.seen.yield_to(need, self.memory_limit);
        if need > self.memory_limit {
            return Err(memory_error(
                self.scene,
                need,
                self.memory_limit,
                format!(
                    "{nodes} quadtree nodes, {vertices} samples, pair tables {} after {} shots",
                    human_bytes(pair_bytes),
                    self.shots
                ),
            ));
        }
        Ok(())
    }

    /// Every vertex of every reflecting polygon gathers G from the history, in
    /// [`GATHER_CHUNKS`] chunks (each in parallel), reporting the time left after each from the
    /// rate so far. Chunking changes no value: each vertex's gather is the same computation.
    fn gather(&mut self) {
        self.tr.index_receivers();
        self.enter(Phase::Gather);
        let work: Vec<(u32, VertexKey)> = self
            .polys
            .iter()
            .enumerate()
            .filter(|(_, p)| p.reflects())
            .flat_map(|(r, p)| p.keys.iter().map(move |&k| (r as u32, k)))
            .collect();
        let chunk = work.len().div_ceil(GATHER_CHUNKS).max(1);
        let mut g: Vec<DVec3> = Vec::with_capacity(work.len());
        for part in work.chunks(chunk) {
            g.extend(self.tr.gather_points(&self.totals, part, &mut self.seen));
            let done = g.len() as f64 / work.len() as f64;
            let now = self.clock.start.elapsed().as_secs_f64();
            self.eta.gather_chunk(self.stage, now, done);
        }
        let mut g = g.into_iter();
        for p in self.polys.iter_mut().filter(|p| p.reflects()) {
            p.g.iter_mut()
                .for_each(|gk| *gk = g.next().expect("one G per vertex"));
        }
    }

    /// A refinement pass against the light at the vertices, then the unshot light re-estimated
    /// from every vertex: the fine integrals hold all the light shot so far (the direct
    /// pass shot to every vertex, a round ends with a full gather), so the coarse estimate
    /// starts again from zero. Returns the number of splits.
    fn refine_and_reestimate(&mut self) -> Result<usize> {
        // The gathers of the refinement need the receiver index sorted.
        self.tr.index_receivers();
        self.refined_after.push(self.shots);
        let splits = refine(
            self.scene,
            self.tr,
            &mut self.polys,
            &self.totals,
            &self.patches,
            (
                self.memory_limit.saturating_sub(self.cache.bytes()),
                &mut self.seen,
            ),
            &mut self.guard_stops,
        )?;
        let all = 0..self.polys.len();
        self.integrate(all.clone(), Light::Fine);
        for p in self.polys.iter_mut() {
            p.clear_coarse();
        }
        self.coarse.iter_mut().for_each(|c| *c = DVec3::ZERO);
        self.concentrated.iter_mut().for_each(|c| *c = DVec3::ZERO);
        self.reestimate(all);
        self.fraction = self.unshot.fraction();
        Ok(splits)
    }

    /// Recomputes the patch integrals of the light `which` of `polygons`.
    fn integrate(&mut self, polygons: impl Iterator<Item = usize>, which: Light) {
        let out = match which {
            Light::Fine => &mut self.fine,
            Light::Coarse => &mut self.coarse,
            Light::Concentrated => &mut self.concentrated,
        };
        for r in polygons {
            self.polys[r].integrate(r, &self.patches, which, out);
        }
    }

    /// Re-estimates the unshot radiosity of the patches of `polygons` from their integrals.
    fn reestimate(&mut self, polygons: impl Iterator<Item = usize>) {
        for r in polygons {
            for s in self.patches.ids(r) {
                let u = self.patch_unshot(s);
                self.unshot.set(self.tr, s, u);
            }
        }
    }

    /// Unshot radiosity of patch `s`: rho * (fine + coarse + concentrated integral) / area -
    /// total, per channel, negative where the patch has shot more than the latest estimate says
    /// it reflects (see the module doc).
    fn patch_unshot(&self, s: usize) -> DVec3 {
        let sg = &self.tr.shooters[s];
        let ShooterKind::Patch { polygon, .. } = sg.kind else {
            return DVec3::ZERO;
        };
        let rho = self.polys[polygon as usize].rho;
        let b = if sg.area > 0.0 {
            rho * (self.fine[s] + self.coarse[s] + self.concentrated[s]) / sg.area
        } else {
            DVec3::ZERO
        };
        b.max(DVec3::ZERO) - self.totals[s]
    }

    /// Every patch's unshot radiosity joins its total, as if shot: the full gather that
    /// follows then carries it one bounce to every vertex (a Jacobi step on the patches'
    /// latest estimates, Gauss-Seidel shooting's remainder included), so a round ends with the
    /// light the coarse shots left unshot one bounce further on instead of missing it. The
    /// totals become the latest estimates of the patches' reflected radiosity, >= 0.
    /// A patch that never shot gets its pair table here (with the memory guard).
    fn flush_unshot(&mut self) -> Result<()> {
        for s in 0..self.totals.len() {
            if matches!(self.tr.shooters[s].kind, ShooterKind::Patch { .. }) {
                let u = self.unshot.radiosity[s];
                if u != DVec3::ZERO {
                    if self.tr.pairs[s].is_none() {
                        self.add_pair_table(s)?;
                    }
                    self.totals[s] = (self.totals[s] + u).max(DVec3::ZERO);
                    self.unshot.set(self.tr, s, DVec3::ZERO);
                }
            }
        }
        Ok(())
    }

    /// The solve enters `phase` of the current round: the progress model learns it (with the
    /// transfers the coming gather will compute) and reports.
    fn enter(&mut self, phase: Phase) {
        let now = self.clock.start.elapsed().as_secs_f64();
        self.eta.enter(phase, self.round, now);
        self.eta.set_gather_transfers(self.gather_transfers());
        self.eta.report(self.stage, now);
    }

    /// Shooters with unshot light and no pair table yet (they will have one by the gather).
    fn unpaired(&self) -> usize {
        let (tr, unshot) = (&*self.tr, &self.unshot.radiosity);
        (0..tr.shooters.len())
            .filter(|&s| tr.pairs[s].is_none() && unshot[s] != DVec3::ZERO)
            .count()
    }

    /// Transfers of the round's gather as far as the shooting can tell: those of the shooters
    /// with pair tables ([`Self::gather_transfers`]), and `unpaired` more shooters at their
    /// mean.
    fn expected_gather_transfers(&self, unpaired: usize) -> f64 {
        let now = self.gather_transfers();
        let paired = self.tr.pairs.iter().filter(|p| p.is_some()).count();
        now + unpaired as f64 * now / paired.max(1) as f64
    }

    /// Transfers of a full gather at the current vertices: every vertex of a reflecting polygon
    /// times the shooters that reach it (as last indexed).
    fn gather_transfers(&self) -> f64 {
        self.polys
            .iter()
            .enumerate()
            .filter(|(_, p)| p.reflects())
            .map(|(r, p)| (p.keys.len() * self.tr.shooters_of(r).len()) as f64)
            .sum()
    }

    /// Sends the line `line` makes of the solver to the observer, if it is tracing.
    fn trace(&self, line: impl FnOnce(&Self) -> String) {
        if self.tracing {
            self.stage.observer().trace(&line(self));
        }
    }

    /// The trace line at the end of a round's shooting: times, shots, the pair tables.
    fn trace_shooting_done(&self) {
        self.trace(|sv| {
            let pairs = PairCounts::of(sv.tr);
            format!(
                "  shooting done {:.0} ms (pairs {:.0} ms, shots {:.0} ms), shots {}, pairs open {} occluded {} (mean cands {:.1}), shooters with total {}, lights given every polygon {}",
                elapsed_ms(sv.clock.start),
                sv.clock.pairs * 1e3,
                sv.clock.shots * 1e3,
                sv.shots,
                pairs.open,
                pairs.occluded,
                pairs.candidates as f64 / pairs.occluded.max(1) as f64,
                sv.totals.iter().filter(|t| **t != DVec3::ZERO).count(),
                sv.tr.exact_fallbacks()
            )
        });
    }

    /// The largest share of its own light a patch has still to shoot (its unshot radiosity
    /// over its total, per channel; negative unshot light counts as much as positive), a
    /// patch darker than [`RESIDUAL_FLOOR`] of the brightest patch's total counted against
    /// that level. The rounds stop only when it is below `convergence` as well as the unshot
    /// fraction of the emitted power, because the fraction misses it wherever most of the
    /// power is absorbed near the lights (a panel 4 cm under a ceiling, facing it, takes nine
    /// tenths of its light back, and its room's walls ended their rounds shooting 3 % more
    /// than they reflect while the fraction read 0.65 %), and wherever the shapes a round
    /// gathered with moved light the coarse shots had taken as uniform (the Cornell box's
    /// rounds ended with a wall patch 5.5 % off its light, the floor between the boxes 3 %
    /// bright); docs/accuracy.md, "Stopping on the residuals".
    fn residual(&self) -> f64 {
        let tr = &*self.tr;
        let is_patch = |s: &usize| matches!(tr.shooters[*s].kind, ShooterKind::Patch { .. });
        let brightest = (0..self.totals.len())
            .filter(is_patch)
            .fold(DVec3::ZERO, |m, s| m.max(self.totals[s]));
        let floor = RESIDUAL_FLOOR * brightest;
        let mut worst = 0.0f64;
        for s in (0..self.totals.len()).filter(is_patch) {
            let (u, t) = (self.unshot.radiosity[s], self.totals[s]);
            for k in 0..3 {
                let level = t[k].max(floor[k]);
                if level > 0.0 {
                    worst = worst.max(u[k].abs() / level);
                }
            }
        }
        worst
    }

    /// Samples of all polygons.
    fn vertices(&self) -> usize {
        self.polys.iter().map(|p| p.keys.len()).sum()
    }

    /// Quadtree nodes of all polygons.
    fn nodes(&self) -> u64 {
        self.polys.iter().map(|p| p.tree.nodes().len() as u64).sum()
    }

    /// Shadow rays cast so far.
    fn rays(&self) -> u64 {
        self.tr.rays.load(Ordering::Relaxed)
    }

    /// The trees with their gathered G, and the history.
    fn into_outcome(mut self) -> Outcome {
        let rays = self.rays();
        self.guard_stops.reflected_power = self.reflected_power();
        let energy = energy::account(
            self.tr,
            &self.polys,
            &self.totals,
            self.unshot.emitted3,
            self.unshot.power3(self.tr),
        );
        self.trace(|_| {
            // Every share in the unit of the other trace lines: per cent of the emitted power
            // (here per channel; a channel that emits nothing shows 0).
            let e = &energy;
            let share = |v: DVec3| {
                let f = |x: f64, of: f64| if of > 0.0 { 100.0 * x / of } else { 0.0 };
                let (a, b) = (v.to_array(), e.emitted.to_array());
                format!("{:.2} {:.2} {:.2}", f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]))
            };
            format!(
                "energy (% of emitted, r g b; emitted {:.4} {:.4} {:.4} W): absorbed {}, unshot {}, escaped {}, error {}",
                e.emitted.x,
                e.emitted.y,
                e.emitted.z,
                share(e.absorbed),
                share(e.unshot),
                share(e.escaped),
                share(e.lost - e.escaped)
            )
        });
        Outcome {
            energy,
            trees: self
                .polys
                .into_iter()
                .map(|p| (p.tree, p.keys, p.g))
                .collect(),
            totals: self.totals,
            kinds: self.tr.shooters.iter().map(|s| s.kind).collect(),
            shapes: (0..self.tr.shooters.len())
                .map(|s| self.tr.shape(s).cloned())
                .collect(),
            shots: self.shots,
            history: self.history,
            unshot: self.fraction,
            emitted: self.unshot.emitted,
            guard_stops: self.guard_stops,
            rays,
            refined_after: self.refined_after,
        }
    }
}

/// The pair tables built so far, for the trace: open and occluded pairs, and the occluder
/// candidates of the occluded ones.
struct PairCounts {
    open: usize,
    occluded: usize,
    candidates: usize,
}

impl PairCounts {
    fn of(tr: &Transfer<'_>) -> Self {
        let mut c = PairCounts {
            open: 0,
            occluded: 0,
            candidates: 0,
        };
        for p in tr.pairs.iter().flatten() {
            for (r, class) in p.receivers() {
                match class {
                    PairClass::Open => c.open += 1,
                    PairClass::Occluded => {
                        c.occluded += 1;
                        c.candidates += p.cands_len(r);
                    }
                    PairClass::Culled => {}
                }
            }
        }
        c
    }
}

/// Patches darker than this share of the brightest patch's total have their residual
/// ([`Solver::residual`]) judged against that level, as the refinement judges a leaf's
/// variation ([`super::refine::REFINE_FLOOR`]): a large relative residual of a light a
/// thousandth of the brightest moves little that anyone sees.
const RESIDUAL_FLOOR: f64 = 1e-2;

/// A share as the trace lines state it: `1.23 %`.
fn percent_of(share: f64) -> String {
    format!("{:.2} %", share * 100.0)
}

/// An unshot fraction of the emitted power as the trace lines state it: `1.23 % of emitted`.
fn percent(fraction: f64) -> String {
    format!("{:.2} % of emitted", fraction * 100.0)
}

/// Most bytes the gathers keep of what they saw ([`SeenCache`]) under `memory_limit`: an
/// eighth of it, and at most [`SEEN_BYTES`].
fn seen_budget(memory_limit: u64) -> u64 {
    (memory_limit / 8).min(SEEN_BYTES)
}

/// The most bytes the gathers keep of what they saw, whatever the memory limit. At their
/// shipped settings the Cornell box keeps 100 MiB and the studio 104 MiB (two thirds of it the
/// regions of patches seen in part); the gallery fills it.
const SEEN_BYTES: u64 = 256 << 20;

/// Most coarse-cache entries (4 bytes each) under `memory_limit`: an eighth of it.
fn cache_budget(memory_limit: u64) -> usize {
    usize::try_from(memory_limit / 8 / 4).unwrap_or(usize::MAX)
}
