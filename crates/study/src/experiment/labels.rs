//! How the results page's tables print sizes and texture settings, shared by every table on it
//! (its sweep, its Table 1 at matched error, its walkthrough errors).

use crate::sweep::SweepPoint;

/// A byte count as the results page prints it (KB, MB; decimal units).
pub(crate) fn mb(bytes: u64) -> String {
    if bytes >= 10_000_000 {
        format!("{:.0} MB", bytes as f64 / 1e6)
    } else if bytes >= 1_000_000 {
        format!("{:.1} MB", bytes as f64 / 1e6)
    } else {
        format!("{:.0} KB", bytes as f64 / 1e3)
    }
}

/// A sweep point's texture as the results page labels it: its scale and texel placement, or
/// `-` for a method that draws no texture.
pub(crate) fn texture_label(p: &SweepPoint) -> String {
    p.texture.map_or("-".into(), |l| {
        format!("1/{}, {}", 1u64 << l.halvings, l.placement)
    })
}
