//! The unshot power of every shooter, the next shooter to shoot and the total unshot power, in
//! a tournament tree: each costs O(log shooters) per change (a scan per shot would make the
//! solve quadratic in the number of shooters).

use glam::DVec3;

/// The shooters' unshot power (per channel, W) and the selection key (the sum over channels of
/// unshot power relative to each channel's emitted power) in a tournament tree: the largest key
/// (ties to the smaller id, as a scan in id order would pick) and the total power, each
/// updated in O(log n) when one shooter changes. The total is summed in the tree's fixed
/// shape, so it does not depend on the order of updates.
pub(super) struct UnshotQueue {
    /// Leaves start at `size`; node k has children 2k and 2k + 1.
    power: Vec<DVec3>,
    best: Vec<(f64, u32)>,
    size: usize,
}

impl UnshotQueue {
    pub(super) fn new(n: usize) -> Self {
        let size = n.next_power_of_two().max(1);
        UnshotQueue {
            power: vec![DVec3::ZERO; 2 * size],
            best: vec![(0.0, u32::MAX); 2 * size],
            size,
        }
    }

    pub(super) fn set(&mut self, s: usize, power: DVec3, key: f64) {
        let mut k = self.size + s;
        self.power[k] = power;
        // Only a positive key can be selected (a NaN never is).
        self.best[k] = (if key > 0.0 { key } else { 0.0 }, s as u32);
        while k > 1 {
            k /= 2;
            let (l, r) = (self.best[2 * k], self.best[2 * k + 1]);
            self.best[k] = if r.0 > l.0 { r } else { l };
            self.power[k] = self.power[2 * k] + self.power[2 * k + 1];
        }
    }

    /// The shooter with the largest positive key, ties to the smaller id.
    pub(super) fn best(&self) -> Option<usize> {
        let (k, s) = self.best[1];
        (k > 0.0).then_some(s as usize)
    }

    /// Unshot power of every shooter, per channel.
    pub(super) fn total(&self) -> DVec3 {
        self.power[1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use base::rng::Rng;

    /// The queue picks what a scan in id order picks (the largest positive key, ties to the
    /// smaller id, none when every key is 0) through random updates, with repeated keys so
    /// ties happen, and its total is the channel sums to rounding.
    #[test]
    fn queue_agrees_with_a_scan() {
        let n = 37;
        let mut q = UnshotQueue::new(n);
        let mut keys = vec![0.0f64; n];
        let mut pw = vec![DVec3::ZERO; n];
        let mut rng = Rng::new(3);
        for step in 0..2000 {
            let s = rng.below(n as u32) as usize;
            let k = if rng.below(4) == 0 {
                0.0
            } else {
                f64::from(rng.below(6))
            };
            let p = DVec3::new(k, 2.0 * k, rng.next_f64());
            keys[s] = k;
            pw[s] = p;
            q.set(s, p, k);
            let mut best = None;
            let mut best_k = 0.0;
            for (i, &x) in keys.iter().enumerate() {
                if x > best_k {
                    best_k = x;
                    best = Some(i);
                }
            }
            assert_eq!(q.best(), best, "step {step}");
            let sum: DVec3 = pw.iter().copied().sum();
            assert!(
                (q.total() - sum).abs().max_element() <= 1e-12 * (1.0 + sum.abs().max_element())
            );
        }
    }
}
