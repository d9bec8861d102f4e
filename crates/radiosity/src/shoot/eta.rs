//! The solve's remaining-time estimate while it shoots (reported through the stage as
//! [`base::progress::Observer::remaining`]); the gather reports its own from its chunks. Only
//! clocks go in and only the estimate comes out: nothing here changes what the solve computes.

use std::time::Instant;

use glam::DVec3;

use super::poly::Poly;
use crate::transfer::Transfer;
use base::progress::Stage;

/// The solve's remaining-time estimate while it shoots. The shots left to the round's target
/// are extrapolated from the number of shots per unit of ln(unshot fraction) over the last
/// [`ETA_WINDOW`] reports (the fraction falls about geometrically in shots); of those, as many
/// as there are patches with unshot light that have not shot yet are priced at the measured
/// cost of a first shot (which finds the shooter's receivers and computes its transfers), the
/// rest at the measured cost of a repeated one (cached transfers): the first shots are the slow
/// ones, and pricing all shots alike overestimates by 2-3 times. Then the round's gather:
/// its transfers (every vertex times the shooters that reach it) at the time per transfer
/// that the shots which computed theirs measured. It covers the current round; refinement and
/// a further round, which the solve cannot know it will need, are not in it (the gather
/// reports its own remaining time when it runs).
pub(super) struct Eta {
    /// (shots this round, ln unshot fraction) at recent reports.
    recent: std::collections::VecDeque<(u64, f64)>,
    last: Option<Instant>,
    /// Shots this round, and the time and count of first and of repeated shots (all rounds).
    shots: u64,
    first: (f64, u64),
    repeat: (f64, u64),
    transfer_secs: f64,
    transfers: u64,
}

/// Reports whose rate the shooting estimate extrapolates (5 s at [`ETA_INTERVAL`]).
const ETA_WINDOW: usize = 10;

/// Seconds between two remaining-time reports.
pub(super) const ETA_INTERVAL: f64 = 0.5;

impl Eta {
    pub(super) fn new() -> Eta {
        Eta {
            recent: std::collections::VecDeque::new(),
            last: None,
            shots: 0,
            first: (0.0, 0),
            repeat: (0.0, 0),
            transfer_secs: 0.0,
            transfers: 0,
        }
    }

    /// A new shooting phase starts (after a gather).
    pub(super) fn phase_start(&mut self) {
        self.recent.clear();
        self.last = None;
        self.shots = 0;
    }

    pub(super) fn transfers(&mut self, n: usize, secs: f64) {
        self.transfers += n as u64;
        self.transfer_secs += secs;
    }

    pub(super) fn shot_took(&mut self, first: bool, secs: f64) {
        self.shots += 1;
        let c = if first {
            &mut self.first
        } else {
            &mut self.repeat
        };
        c.0 += secs;
        c.1 += 1;
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn shot(
        &mut self,
        stage: &Stage<'_>,
        tr: &Transfer<'_>,
        polys: &[Poly],
        unshot: &[DVec3],
        frac: f64,
        target: f64,
        round: u32,
    ) {
        if self
            .last
            .is_some_and(|l| l.elapsed().as_secs_f64() < ETA_INTERVAL)
        {
            return;
        }
        self.last = Some(Instant::now());
        let now = (self.shots, frac.ln());
        if self.recent.len() == ETA_WINDOW {
            self.recent.pop_front();
        }
        self.recent.push_back(now);
        let Some(&(s0, l0)) = self.recent.front() else {
            return;
        };
        let fallen = l0 - now.1;
        if fallen.is_nan() || fallen <= 0.0 || self.transfers == 0 {
            return;
        }
        let left = if frac > target {
            (now.0 - s0) as f64 / fallen * (frac / target).ln()
        } else {
            0.0
        };
        let mean = |(t, n): (f64, u64)| if n > 0 { t / n as f64 } else { 0.0 };
        let unpaired = (0..tr.shooters.len())
            .filter(|&s| tr.pairs[s].is_none() && unshot[s] != DVec3::ZERO)
            .count() as f64;
        let firsts = left.min(unpaired);
        let repeat = if self.repeat.1 > 0 {
            mean(self.repeat)
        } else {
            mean(self.first)
        };
        let shooting = firsts * mean(self.first) + (left - firsts) * repeat;
        let gather: f64 = polys
            .iter()
            .enumerate()
            .filter(|(_, p)| p.rho.max_element() > 0.0)
            .map(|(r, p)| (p.keys.len() * tr.shooters_of(r).len()) as f64)
            .sum();
        let per = self.transfer_secs / self.transfers as f64;
        stage.remaining(&format!("round {round} shooting"), shooting + gather * per);
    }
}
