//! TEMPORARY stub; replaced by the observer branch on merge.
/// Observer.
pub trait Observer: Sync {
    /// Progress.
    fn progress(&self, _stage: &str, _fraction: f64) {}
    /// Finished.
    fn finished(&self, _stage: &str) {}
    /// Tracing wanted.
    fn tracing(&self) -> bool {
        false
    }
    /// A trace line.
    fn trace(&self, _line: &str) {}
}
/// Silent.
pub struct Silent;
impl Observer for Silent {}
