//! The light every shooter has still to shoot: its unshot radiosity and power, the next shooter
//! and the solve's unshot fraction, against which convergence is judged per channel.

use glam::DVec3;

use super::queue::UnshotQueue;
use crate::transfer::{spot_power, spot_power3, ShooterKind, Transfer};

/// The unshot light of every shooter, the emitted power it is measured against, and the queue
/// that picks the next shooter.
pub(super) struct Unshot {
    /// Per shooter: unshot radiosity (W/m^2 per channel); a spot's is 1 in every channel until
    /// it has shot (its intensity is in the scene).
    pub(super) radiosity: Vec<DVec3>,
    /// Every shooter's unshot power, their sum and the largest, updated per shooter in
    /// O(log shooters), so a shot costs what it reaches, not the scene's size.
    queue: UnshotQueue,
    /// Emitted power, summed over channels (W).
    pub(super) emitted: f64,
    /// Per channel: one over the emitted power, 0 for a channel nothing emits in (it needs no
    /// shooting).
    inv_emitted: [f64; 3],
    /// Emitted power per channel (W).
    pub(super) emitted3: DVec3,
}

impl Unshot {
    /// Spots and emitters hold their emission, patches nothing yet.
    pub(super) fn new(tr: &Transfer<'_>) -> Self {
        let ns = tr.shooters.len();
        let mut radiosity = vec![DVec3::ZERO; ns];
        let mut emitted = 0.0;
        for (s, sg) in tr.shooters.iter().enumerate() {
            match sg.kind {
                ShooterKind::Spot { spot } => {
                    emitted += spot_power(&tr.scene.spots[spot as usize]);
                    radiosity[s] = DVec3::ONE;
                }
                ShooterKind::Emitter { polygon } => {
                    let e = tr.scene.material_of(polygon as usize).emission;
                    emitted += sg.area * (e.x + e.y + e.z);
                    radiosity[s] = e;
                }
                ShooterKind::Patch { .. } => {}
            }
        }
        let emitted3: DVec3 = (0..ns)
            .filter(|&s| !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. }))
            .map(|s| power3(tr, s, radiosity[s]))
            .sum();
        let inv_emitted = emitted3
            .to_array()
            .map(|e| if e > 0.0 { 1.0 / e } else { 0.0 });
        let mut unshot = Unshot {
            radiosity,
            queue: UnshotQueue::new(ns),
            emitted,
            inv_emitted,
            emitted3,
        };
        for s in 0..ns {
            unshot.enqueue(tr, s);
        }
        unshot
    }

    /// Sets shooter `s`'s unshot radiosity to `u`.
    pub(super) fn set(&mut self, tr: &Transfer<'_>, s: usize, u: DVec3) {
        self.radiosity[s] = u;
        self.enqueue(tr, s);
    }

    /// Shooter `s`'s place in the queue: its unshot power, and as key the sum over channels of
    /// that power relative to the channel's emitted power (so the channel furthest from
    /// convergence is served first).
    fn enqueue(&mut self, tr: &Transfer<'_>, s: usize) {
        let p = power3(tr, s, self.radiosity[s]).abs();
        let f = self.fractions(p);
        self.queue.set(s, p, f.x + f.y + f.z);
    }

    /// Power `p` of each channel as a fraction of that channel's emitted power.
    fn fractions(&self, p: DVec3) -> DVec3 {
        let inv = self.inv_emitted;
        DVec3::new(p.x * inv[0], p.y * inv[1], p.z * inv[2])
    }

    /// The solve's unshot fraction: unshot over emitted power in the channel where it is largest
    /// (0 when nothing emits).
    pub(super) fn fraction(&self) -> f64 {
        if self.emitted <= 0.0 {
            return 0.0;
        }
        self.fractions(self.queue.total()).max_element()
    }

    /// Unshot power per channel (W), summed over shooters in id order.
    pub(super) fn power3(&self, tr: &Transfer<'_>) -> DVec3 {
        (0..self.radiosity.len())
            .map(|s| power3(tr, s, self.radiosity[s]))
            .sum()
    }

    /// The next shooter: the largest key (see `enqueue`), ties by the smaller id; none when
    /// nothing is left to shoot.
    pub(super) fn next(&self) -> Option<usize> {
        self.queue.best()
    }
}

/// Unshot power of shooter `s` per channel (W) for unshot radiosity `u`: a spot's is its power
/// in each channel until it has shot.
fn power3(tr: &Transfer<'_>, s: usize, u: DVec3) -> DVec3 {
    match tr.shooters[s].kind {
        ShooterKind::Spot { spot } => {
            if u == DVec3::ZERO {
                DVec3::ZERO
            } else {
                spot_power3(&tr.scene.spots[spot as usize])
            }
        }
        _ => tr.shooters[s].area * u,
    }
}

/// Unshot power of shooter `s` for unshot radiosity `u`, summed over channels (W).
pub(super) fn power(tr: &Transfer<'_>, s: usize, u: DVec3) -> f64 {
    let p = power3(tr, s, u);
    p.x + p.y + p.z
}
