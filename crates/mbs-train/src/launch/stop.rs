//! Stop requests from outside the process: Ctrl-C, SIGTERM and SIGUSR1 set
//! one flag, and the run stops at its next step with a checkpoint. Opt-in
//! ([`stop_requests`]), so that a host that embeds the library (a Python
//! interpreter) keeps its own handlers unless it asks.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use super::LaunchError;

/// The flag that Ctrl-C, SIGTERM and SIGUSR1 set to stop a run with a
/// checkpoint; a second Ctrl-C while it is written ends the process at
/// once (exit status 130). Installs process-wide handlers: call it once.
pub fn stop_requests() -> Result<Arc<AtomicBool>, LaunchError> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::Relaxed) {
            std::process::exit(130);
        }
    })
    .map_err(|e| LaunchError::Handler {
        signal: "Ctrl-C",
        source: Box::new(e),
    })?;
    // SIGUSR1 stops the same way. mpirun forwards it to every rank at once,
    // where its Ctrl-C reaches them as SIGTERM only after
    // `odls_base_sigkill_timeout` seconds, with SIGKILL as long after.
    #[cfg(unix)]
    signal_hook::flag::register(signal_hook::consts::SIGUSR1, Arc::clone(&stop)).map_err(|e| {
        LaunchError::Handler {
            signal: "SIGUSR1",
            source: Box::new(e),
        }
    })?;
    Ok(stop)
}
