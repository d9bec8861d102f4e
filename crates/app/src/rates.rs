//! Summaries of measured times that every timing command shares: the median, the range, and the
//! frame rate of a frame time. Kept apart from the commands so that none of them has to reach
//! into another for them.

/// The smallest and largest of `xs` (`[inf, 0]` for none; the values are times and rates, >= 0).
pub fn min_max(xs: &[f64]) -> [f64; 2] {
    [
        xs.iter().copied().fold(f64::INFINITY, f64::min),
        xs.iter().copied().fold(0.0, f64::max),
    ]
}

/// The median of `xs` (the mean of the middle two for an even count; 0 for none).
pub fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

/// Frames per second of a frame time in ms (0 for a time of 0).
pub fn fps(frame_ms: f64) -> f64 {
    if frame_ms > 0.0 {
        1e3 / frame_ms
    } else {
        0.0
    }
}
