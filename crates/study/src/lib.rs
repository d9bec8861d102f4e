//! The studies: what a researcher runs to compare the reconstructions, speed against error.
//! [`sweep`] measures every method over sampling densities and texture sizes (errors against the
//! converged solution and, with a path-traced [`physics`] truth, against the light; the texture
//! memory that matches the direct method's error in [`equal_error`] and [`equal_views`]);
//! [`timing`] measures frame times in separate worker processes for their confidence intervals
//! (its protocol knows no study: [`worker`] dispatches to [`sweep`] and [`walk_timing`]);
//! [`experiment`] reruns the paper's Fig. 5, Fig. 6 and Table 1 and writes the results page;
//! [`plot`] draws the sweeps.
//!
//! Built on the application ([`app`]: prepared solutions, frames, the commands' summaries); like
//! it, a study prints nothing and reports progress through [`base::progress::Observer`]. It is
//! the one crate that draws plots.

#![forbid(unsafe_code)]

pub mod timing;
pub mod physics;
pub mod equal_error;
pub mod equal_views;
pub mod sweep;
pub mod walk_timing;
pub mod worker;
pub mod plot;
pub mod experiment;
