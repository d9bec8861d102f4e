//! The solve's progress: an estimate of the work done over the whole work, and of the seconds
//! left, reported through the stage ([`base::progress::Stage::advance`] and
//! [`base::progress::Observer::remaining`]). Only clocks and counts go in and only the reports
//! come out: nothing here changes what the solve computes.
//!
//! Work is counted in estimated seconds. A solve is the direct pass and its refinement, then
//! rounds of shooting, a full gather and a refinement (see the parent module). The seconds
//! already spent are work done; the work left is priced phase by phase from rates measured in
//! this solve: the shots left to the round's target from the unshot fraction's decay on a log
//! scale, the gather's transfers (every vertex times the shooters that reach it) at the time per
//! transfer of the last gather (before the first, of the shots that computed theirs), the
//! refinement at the ratio of refinement to gather time the last round measured, and the rounds
//! still expected ([`EXPECTED_ROUNDS`], then [`P_ANOTHER_ROUND`] of one more). The fraction is
//! done / (done + left); a phase that overruns its estimate is priced at a share of its time so
//! far ([`OVERRUN`]), so the estimate of seconds left grows instead of sitting at 0 while work
//! remains. The work done is the solve's own clock, so the fraction follows work whatever the
//! machine's load; the tests drive the model with a synthetic clock.

use std::collections::VecDeque;

use base::progress::Stage;

/// The phase a solve is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Phase {
    /// The direct pass (and, as round 0, its refinement).
    Direct,
    /// A round's indirect shooting.
    Shooting,
    /// A round's full gather.
    Gather,
    /// A round's refinement and re-estimate.
    Refine,
}

/// Rounds a solve is expected to run before it has seen otherwise: the first round gathers with
/// flat patch shapes, so a second one nearly always follows.
pub(super) const EXPECTED_ROUNDS: u32 = 2;

/// After the expected rounds, the weight of one more round in the work left (the shipped scenes
/// run 2 or 3 rounds).
const P_ANOTHER_ROUND: f64 = 0.3;

/// Refinement seconds per gather second before any round has measured it.
const REFINE_RATIO: f64 = 0.5;

/// The next round's gather over this one's: more vertices after the refinement, and, after the
/// first round, patch shapes that make a transfer dearer (measured 0.54 to 1.47 s on the Cornell
/// box, 2.8 to 4.2 s on the gallery; later rounds grow by the refinement's new vertices).
const GROWTH_AFTER_FIRST: f64 = 1.5;
const GROWTH_LATER: f64 = 1.2;

/// A phase past its estimate is priced at this share of its time so far (so the seconds left
/// grow with the overrun and never reach 0).
pub(super) const OVERRUN: f64 = 0.25;

/// Reports whose rate the shooting estimate extrapolates.
const ETA_WINDOW: usize = 10;

/// Seconds between two reports while shooting.
pub(super) const ETA_INTERVAL: f64 = 0.5;

/// The progress model of one solve. Times are seconds since the solve started.
pub(super) struct Eta {
    phase: Phase,
    round: u32,
    phase_start: f64,
    last_report: Option<f64>,
    /// While shooting: (shots this round, ln unshot fraction) at recent reports, the ln fraction
    /// and target when the round's shooting started, and the latest.
    recent: VecDeque<(u64, f64)>,
    shots: u64,
    ln_start: Option<f64>,
    ln_now: f64,
    ln_target: f64,
    /// Time and count of first and of repeated shots (all rounds).
    first: (f64, u64),
    repeat: (f64, u64),
    /// Shooters with unshot light that have not shot yet (at the latest report).
    unpaired: f64,
    /// Seconds and transfers of the shots that computed their transfers.
    transfer_secs: f64,
    transfers: u64,
    /// Transfers of the coming (or running) gather, and its share done.
    gather_transfers: f64,
    gather_done: f64,
    /// The last gather: seconds per transfer and seconds.
    gather_rate: Option<f64>,
    gather_secs: f64,
    /// Refinement over gather seconds, from the last round that measured both.
    refine_ratio: Option<f64>,
}

impl Eta {
    pub(super) fn new() -> Eta {
        Eta {
            phase: Phase::Direct,
            round: 0,
            phase_start: 0.0,
            last_report: None,
            recent: VecDeque::new(),
            shots: 0,
            ln_start: None,
            ln_now: 0.0,
            ln_target: 0.0,
            first: (0.0, 0),
            unpaired: 0.0,
            repeat: (0.0, 0),
            transfer_secs: 0.0,
            transfers: 0,
            gather_transfers: 0.0,
            gather_done: 0.0,
            gather_rate: None,
            gather_secs: 0.0,
            refine_ratio: None,
        }
    }

    /// The solve enters `phase` of round `round` at `now`; the phase that ends records what it
    /// measured (a gather its rate, a round's refinement its ratio to the gather).
    pub(super) fn enter(&mut self, phase: Phase, round: u32, now: f64) {
        if std::env::var_os("ETA_DEBUG").is_some() { eprintln!("ETA enter {:?} {} {:.3} prev {:?} gt {} first {:?} rep {:?} tr {} {}", phase, round, now, self.phase, self.gather_transfers, self.first, self.repeat, self.transfers, self.transfer_secs); }
        let secs = now - self.phase_start;
        match self.phase {
            Phase::Gather if self.gather_transfers > 0.0 => {
                self.gather_rate = Some(secs / self.gather_transfers);
                self.gather_secs = secs;
            }
            Phase::Refine if self.round > 0 && self.gather_secs > 0.0 => {
                self.refine_ratio = Some(secs / self.gather_secs);
            }
            _ => {}
        }
        (self.phase, self.round, self.phase_start) = (phase, round, now);
        self.recent.clear();
        self.shots = 0;
        self.ln_start = None;
        self.gather_done = 0.0;
        self.last_report = None;
    }

    /// The transfers the coming gather will compute (every vertex times its shooters).
    pub(super) fn set_gather_transfers(&mut self, n: f64) {
        if std::env::var_os("ETA_DEBUG").is_some() { eprintln!("ETA set_gt {}", n); }
        self.gather_transfers = n;
    }

    /// `n` transfers were computed in `secs` (by a shot).
    pub(super) fn transfers(&mut self, n: usize, secs: f64) {
        self.transfers += n as u64;
        self.transfer_secs += secs;
    }

    /// A shot took `secs` (`first`: the shooter's first, which finds its receivers).
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

    /// Whether a report is due at `now` (at most one every [`ETA_INTERVAL`] while shooting).
    pub(super) fn due(&self, now: f64) -> bool {
        self.last_report.is_none_or(|l| now - l >= ETA_INTERVAL)
    }

    /// After a shot: unshot fraction `frac` against the round's `target`; when a report is
    /// [`due`](Self::due), `counts` gives the shooters with unshot light that have not shot yet
    /// and the transfers the round's gather is expected to compute, and the model reports.
    pub(super) fn shot(
        &mut self,
        stage: &mut Stage<'_>,
        now: f64,
        (frac, target): (f64, f64),
        counts: Option<(usize, f64)>,
    ) {
        if self.phase != Phase::Shooting || frac <= 0.0 {
            return;
        }
        self.ln_now = frac.ln();
        self.ln_target = target.max(f64::MIN_POSITIVE).ln();
        self.ln_start.get_or_insert(self.ln_now);
        let Some((unpaired, transfers)) = counts else {
            return;
        };
        if self.recent.len() == ETA_WINDOW {
            self.recent.pop_front();
        }
        self.recent.push_back((self.shots, self.ln_now));
        self.unpaired = unpaired as f64;
        self.gather_transfers = transfers;
        self.report(stage, now);
    }

    /// The gather has done `done` of its transfers.
    pub(super) fn gather_chunk(&mut self, stage: &mut Stage<'_>, now: f64, done: f64) {
        self.gather_done = done;
        self.report(stage, now);
    }

    /// Reports the fraction done and the seconds left at `now` (nothing before the first
    /// rate is measured: the direct pass shows 0).
    pub(super) fn report(&mut self, stage: &mut Stage<'_>, now: f64) {
        self.last_report = Some(now);
        let Some(left) = self.left(now) else {
            return;
        };
        // In round 0 only the lights have pair tables, so the gathers' transfers are not known
        // yet: the fraction waits for the first round (the direct light is a few per cent).
        // A round's shooting learns the gather's transfers at its first report.
        let counted = self.phase != Phase::Shooting || !self.recent.is_empty();
        if self.round > 0 && counted {
            stage.advance(now / (now + left));
        }
        let phase = match self.phase {
            // Every label starts with its round ("round 0" is the direct light's).
            Phase::Direct => "round 0 direct light".to_string(),
            Phase::Refine if self.round == 0 => "round 0 direct light refinement".to_string(),
            Phase::Shooting => format!("round {} shooting", self.round),
            Phase::Gather => format!("round {} gather", self.round),
            Phase::Refine => format!("round {} refinement", self.round),
        };
        stage.remaining(&phase, left);
    }

    /// Estimated seconds left of the whole solve at `now`, if any rate is known.
    pub(super) fn left(&self, now: f64) -> Option<f64> {
        let per = self
            .gather_rate
            .or_else(|| (self.transfers > 0).then(|| self.transfer_secs / self.transfers as f64))?;
        let gather = self.gather_transfers * per;
        let refine = self.refine_ratio.unwrap_or(REFINE_RATIO) * gather;
        let spent = now - self.phase_start;
        let overrun = |est: f64| est.max(OVERRUN * spent);
        let this_round = match self.phase {
            Phase::Direct => overrun(0.0) + gather + refine,
            Phase::Shooting => overrun(self.shooting_left(spent)) + gather + refine,
            Phase::Gather => {
                let d = self.gather_done;
                let est = if d >= 1.0 / 16.0 {
                    spent * (1.0 - d) / d
                } else {
                    gather * (1.0 - d)
                };
                overrun(est) + refine
            }
            Phase::Refine => overrun(refine - spent),
        };
        Some(this_round + self.later_rounds(gather + refine))
    }

    /// Seconds of the rounds expected after this one, a round of `unit` seconds (gather and
    /// refinement at today's vertices) growing by [`GROWTH_AFTER_FIRST`] into round 2 and by
    /// [`GROWTH_LATER`] after; rounds up to [`EXPECTED_ROUNDS`] count whole, one more at
    /// [`P_ANOTHER_ROUND`].
    fn later_rounds(&self, unit: f64) -> f64 {
        let mut cost = unit;
        let mut sum = 0.0;
        let extra = self.round.max(EXPECTED_ROUNDS) + 1;
        for r in self.round + 1..=super::MAX_ROUNDS {
            if r >= 2 {
                cost *= if r == 2 {
                    GROWTH_AFTER_FIRST
                } else {
                    GROWTH_LATER
                };
            }
            if r <= EXPECTED_ROUNDS {
                sum += cost;
            } else if r == extra {
                sum += P_ANOTHER_ROUND * cost;
            }
        }
        sum
    }

    /// Seconds of shooting left to the round's target after `spent` seconds of it: the shots
    /// left from the shots per unit of ln(unshot fraction) over the recent reports, priced at
    /// the measured cost of a first shot for as many as there are shooters that have not shot,
    /// the rest at that of a repeated one; before two reports, the time so far scaled by the
    /// log-scale distance still to go.
    fn shooting_left(&self, spent: f64) -> f64 {
        let to_go = (self.ln_now - self.ln_target).max(0.0);
        if to_go == 0.0 {
            return 0.0;
        }
        let mean = |(t, n): (f64, u64)| if n > 0 { t / n as f64 } else { 0.0 };
        if let (Some(&(s0, l0)), Some(&(s1, l1))) = (self.recent.front(), self.recent.back()) {
            let fallen = l0 - l1;
            if fallen > 0.0 && s1 > s0 {
                let left = (s1 - s0) as f64 / fallen * to_go;
                let firsts = left.min(self.unpaired);
                let repeat = if self.repeat.1 > 0 {
                    mean(self.repeat)
                } else {
                    mean(self.first)
                };
                return firsts * mean(self.first) + (left - firsts) * repeat;
            }
        }
        let done = self.ln_start.map_or(0.0, |l| l - self.ln_now);
        if done > 0.0 {
            spent * to_go / done
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use base::progress::{Event, Recorder};

    /// The fractions the recorder saw, in order.
    fn fractions(r: &Recorder) -> Vec<f64> {
        r.events()
            .into_iter()
            .filter_map(|e| match e {
                Event::Progress(_, f) => Some(f),
                _ => None,
            })
            .collect()
    }

    /// A synthetic solve on a synthetic clock (no timing): a 1 s direct pass of 1000 transfers,
    /// then two rounds of 100 shots of 0.1 s each (the unshot fraction falling geometrically
    /// from 0.5 to the target), a 16-chunk gather of 10,000 transfers and a refinement. The
    /// fractions never decrease and end at 1, and after half the first round's shots the
    /// fraction is far from 1: the gathers and the second round are still to come, whatever
    /// the unshot fraction says.
    #[test]
    fn the_fraction_follows_work_not_shots() {
        let r = Recorder::default();
        let mut stage = Stage::start(&r, "solve");
        let mut eta = Eta::new();
        let mut now = 1.0;
        eta.transfers(1000, 1.0);
        eta.enter(Phase::Refine, 0, now);
        eta.set_gather_transfers(10_000.0);
        eta.report(&mut stage, now);
        now += 1.0;
        let mut after_half = None;
        for round in 1..=2 {
            eta.enter(Phase::Shooting, round, now);
            let (start, target) = (0.5_f64, 0.005_f64);
            for i in 1..=100 {
                now += 0.1;
                eta.shot_took(i == 1, 0.1);
                let frac = start * (target / start).powf(i as f64 / 100.0);
                let counts = eta.due(now).then_some((0, 10_000.0));
                eta.shot(&mut stage, now, (frac, target), counts);
                if round == 1 && i == 50 {
                    after_half = fractions(&r).last().copied();
                }
            }
            eta.enter(Phase::Gather, round, now);
            for chunk in 1..=16 {
                now += 10.0 / 16.0;
                eta.gather_chunk(&mut stage, now, chunk as f64 / 16.0);
            }
            eta.enter(Phase::Refine, round, now);
            eta.report(&mut stage, now);
            now += 5.0;
        }
        stage.advance(1.0);
        let f = fractions(&r);
        assert!(f.windows(2).all(|w| w[0] <= w[1]), "{f:?}");
        assert_eq!(f.last(), Some(&1.0));
        // Half the first round's shots: 7 s of about 53 s of work (0.13); the shots' own
        // log-scale distance to the target would say 0.5 and more.
        let half = after_half.expect("a report by then");
        assert!(half > 0.0 && half < 0.35, "{half}");
    }

    /// A phase past its estimate never reports 0 s left: the estimate grows with the overrun.
    #[test]
    fn an_overrunning_phase_reports_time_left_that_grows() {
        let mut eta = Eta::new();
        eta.transfers(100, 1.0);
        eta.enter(Phase::Refine, 3, 0.0);
        eta.set_gather_transfers(100.0);
        // A refinement estimated at REFINE_RATIO of a 1 s gather, still running at 2 s and 4 s.
        let at2 = eta.left(2.0).expect("a rate");
        let at4 = eta.left(4.0).expect("a rate");
        assert!(at2 >= OVERRUN * 2.0, "{at2}");
        assert!(at4 > at2, "{at2} then {at4}");
    }
}
