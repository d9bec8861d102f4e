//! The timing worker's dispatch (`pixelflow-sim time-worker <request>`): the one place that
//! names every job a worker can run, so that [`crate::timing`] knows the protocol and none of
//! its clients, and no client knows another.

use crate::sweep::WorkerRequest as SweepRequest;
use crate::timing::{job_of, serve, WorkerTask};
use crate::walk_timing::WalkWorkerRequest;
use app::context::Context;
use base::error::{Error, Result};

/// Runs a worker's `request` (JSON, as [`crate::timing::request_json`] wrote it) and returns
/// its reply as JSON ([`crate::timing::WorkerReply`]); a job no study offers is an
/// [`Error::InvalidOption`].
pub fn run_worker(job: &Context<'_>, request: &str) -> Result<String> {
    let name = job_of(request)?;
    if name == SweepRequest::JOB {
        serve::<SweepRequest>(job, request)
    } else if name == WalkWorkerRequest::JOB {
        serve::<WalkWorkerRequest>(job, request)
    } else {
        Err(Error::invalid_option(
            "time-worker",
            request,
            format!("asks for job `{name}`, which no study offers"),
        ))
    }
}
