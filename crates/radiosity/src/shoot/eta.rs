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
//! refinement at the ratio of refinement to gather time the last round measured (falling round
//! by round, [`REFINE_DECAY_FIRST`], [`REFINE_DECAY_LATER`]; before the first round's, from the
//! direct light's refinement, [`REFINE_FROM_DIRECT`]), and the rounds still expected, each
//! weighted by the chance it runs. A round's refinement moves the solution as much as it grows
//! the mesh, so the growth of the gather's transfers by a refinement prices the next gather
//! (the first round's, estimated from its refinement's time) and says whether the round after
//! the next is likely ([`p_another`]): on the shipped scenes a round whose refinement grew the
//! mesh by 40 % or more was followed by two more, one that grew it by 16 % or less by one. The
//! fraction is done / (done + left), a silent phase (a refinement after the first reports
//! nothing until it ends) counted half done when it starts, so the bar is as far from the truth at its start as
//! at its end; a phase that overruns its estimate is priced at a share of its time so far
//! ([`OVERRUN`]), so the estimate of seconds left grows instead of sitting at 0 while work
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

/// Refinement seconds per gather second when nothing better is known.
const REFINE_RATIO: f64 = 0.5;

/// The first round's refinement over the direct light's (measured 2.5 on the Cornell box, 4.5 on
/// the gallery, about 7 on gallery-fine): 4.5 keeps the largest gap between the fraction and
/// elapsed/total under 0.15 on all three (docs/performance.md).
const REFINE_FROM_DIRECT: f64 = 4.5;

/// A round's refinement-to-gather ratio over the previous round's: into round 2 (measured 0.66
/// on the Cornell box, 0.57 on the gallery) and after (0.64, 0.74 on gallery-fine).
const REFINE_DECAY_FIRST: f64 = 0.5;
const REFINE_DECAY_LATER: f64 = 0.7;

/// Round 2's seconds per transfer over round 1's (flat shapes), per unit of growth of the
/// transfers by round 1's refinement (1.55 at a growth of 0.69 on the Cornell box, 1.02 at 0.16
/// on the gallery).
const SHAPED_RATE_PER_GROWTH: f64 = 0.8;

/// The first refinement's growth of the transfers per unit of its refinement-to-gather ratio
/// (0.69 at 1.13 on the Cornell box, 0.16 at 0.35 on the gallery).
const GROWTH_PER_REFINE_RATIO: f64 = 0.5;

/// A later refinement's growth over the previous one's (0.14 after 0.69 on the Cornell box).
const GROWTH_DECAY: f64 = 0.2;

/// A gather after round 2's over the previous one (1.3 on the Cornell box, 1.18 on
/// gallery-fine).
const GROWTH_LATER: f64 = 1.2;

/// The chance that another round follows round `r`, from the growth `g` of the transfers by
/// round `r - 1`'s refinement: a refinement that moved the mesh much moved the light, and the
/// next gather then finds unshot light above the threshold or changed shapes.
fn p_another(g: f64) -> f64 {
    ((g - 0.15) / 0.2).clamp(0.15, 0.85)
}

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
    /// Refinement over gather seconds, from the last round that measured both, and that round.
    refine_ratio: Option<f64>,
    refine_round: u32,
    /// The round of the last gather, and its transfers.
    gather_round: u32,
    last_gather_transfers: f64,
    /// Seconds of the direct light's refinement (round 0).
    refine0: Option<f64>,
    /// Growth of the gather's transfers by the refinement of round 1 and of round 2.
    growth: [Option<f64>; 2],
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
            refine_round: 0,
            gather_round: 0,
            last_gather_transfers: 0.0,
            refine0: None,
            growth: [None; 2],
        }
    }

    /// The solve enters `phase` of round `round` at `now`; the phase that ends records what it
    /// measured (a gather its rate, a round's refinement its ratio to the gather).
    pub(super) fn enter(&mut self, phase: Phase, round: u32, now: f64) {
        let secs = now - self.phase_start;
        match self.phase {
            Phase::Gather if self.gather_transfers > 0.0 => {
                self.gather_rate = Some(secs / self.gather_transfers);
                self.gather_secs = secs;
                self.gather_round = self.round;
                self.last_gather_transfers = self.gather_transfers;
            }
            Phase::Refine if self.round == 0 => self.refine0 = Some(secs),
            Phase::Refine if self.gather_secs > 0.0 => {
                self.refine_ratio = Some(secs / self.gather_secs);
                self.refine_round = self.round;
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
    /// At the start of a round's shooting they tell how much the last refinement grew the mesh.
    pub(super) fn set_gather_transfers(&mut self, n: f64) {
        self.gather_transfers = n;
        let r = self.round as usize;
        if self.phase == Phase::Shooting
            && (2..=3).contains(&r)
            && self.gather_round + 1 == self.round
            && self.last_gather_transfers > 0.0
        {
            self.growth[r - 2] = Some((n / self.last_gather_transfers - 1.0).max(0.0));
        }
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
            // The refinement reports nothing until it ends: counted half done now, the bar
            // is as far ahead at its start as it is behind at its end (once a round has
            // measured a refinement: the first one's estimate is only a guess).
            let credit = match self.phase {
                Phase::Refine if self.round >= 2 => 0.5 * self.refine_left(now).min(left),
                _ => 0.0,
            };
            stage.advance((now + credit) / (now + left));
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
        let gather = self.gather_estimate()?;
        let ratio = self.refine_ratio_now(gather);
        let refine = ratio * gather;
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
        Some(this_round + self.later_rounds(gather, ratio))
    }

    /// Seconds of the refinement left at `now` (0 outside one), as [`Self::left`] prices it.
    fn refine_left(&self, now: f64) -> f64 {
        let Some(gather) = self.gather_estimate() else {
            return 0.0;
        };
        let refine = self.refine_ratio_now(gather) * gather;
        let spent = now - self.phase_start;
        (refine - spent).max(OVERRUN * spent)
    }

    /// Seconds of this round's gather (the one that ran, in the refinement): its transfers at
    /// the last gather's time per transfer (before the first, at the shots'), round 2's dearer
    /// than round 1's by its shapes ([`SHAPED_RATE_PER_GROWTH`]).
    fn gather_estimate(&self) -> Option<f64> {
        let per = self
            .gather_rate
            .or_else(|| (self.transfers > 0).then(|| self.transfer_secs / self.transfers as f64))?;
        let shaped = if self.round >= 2 && self.gather_round <= 1 && self.phase != Phase::Refine {
            1.0 + SHAPED_RATE_PER_GROWTH * self.growth[0].unwrap_or(0.0)
        } else {
            1.0
        };
        Some(self.gather_transfers * per * shaped)
    }

    /// Refinement over gather seconds for this round's refinement, `gather` its gather.
    fn refine_ratio_now(&self, gather: f64) -> f64 {
        match self.refine_ratio {
            Some(r) if self.refine_round >= 1 && self.refine_round < self.round => {
                let decay = if self.round == 2 {
                    REFINE_DECAY_FIRST
                } else {
                    REFINE_DECAY_LATER
                };
                r * decay.powi((self.round - self.refine_round) as i32)
            }
            Some(r) if self.refine_round == self.round => r,
            _ => match self.refine0 {
                Some(r0) if r0 > 0.0 && gather > 0.0 && self.round <= 1 => {
                    REFINE_FROM_DIRECT * r0 / gather
                }
                _ => REFINE_RATIO,
            },
        }
    }

    /// Seconds of the rounds expected after this one, from this round's `gather` seconds and
    /// refinement `ratio`: round 2's gather grows with round 1's refinement (its transfers and
    /// its shapes, [`GROWTH_PER_REFINE_RATIO`], [`SHAPED_RATE_PER_GROWTH`]), later ones by
    /// [`GROWTH_LATER`]; the refinement ratio falls ([`REFINE_DECAY_FIRST`],
    /// [`REFINE_DECAY_LATER`]). Rounds up to [`EXPECTED_ROUNDS`] count whole, a later one at the
    /// chance that it runs ([`p_another`] of the growth by the refinement two rounds before it,
    /// measured or estimated).
    fn later_rounds(&self, gather: f64, ratio: f64) -> f64 {
        // Growth by round 1's refinement: measured, else from its refinement ratio.
        let g1 = self.growth[0].unwrap_or_else(|| {
            let ratio1 = if self.round <= 1 {
                ratio
            } else {
                self.refine_ratio.unwrap_or(REFINE_RATIO)
            };
            GROWTH_PER_REFINE_RATIO * ratio1
        });
        let g2 = self.growth[1].unwrap_or(GROWTH_DECAY * g1);
        let growth_of = |k: u32| match k {
            1 => Some(g1),
            2 => Some(g2),
            _ => None,
        };
        let (mut gather, mut ratio) = (gather, ratio);
        let (mut weight, mut sum) = (1.0, 0.0);
        for k in self.round + 1..=super::MAX_ROUNDS {
            if k == 2 {
                gather *= (1.0 + g1) * (1.0 + SHAPED_RATE_PER_GROWTH * g1);
                ratio *= REFINE_DECAY_FIRST;
            } else {
                gather *= GROWTH_LATER;
                ratio *= REFINE_DECAY_LATER;
            }
            if k > EXPECTED_ROUNDS {
                let g = growth_of(k - 2).unwrap_or(GROWTH_DECAY * g2);
                weight *= p_another(g);
            }
            sum += weight * gather * (1.0 + ratio);
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
