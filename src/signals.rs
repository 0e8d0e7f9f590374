//! SIGINT and SIGTERM: nothing half-written is left behind. A command that can stop early (a
//! long `dvrk sim`) asks for [`stop_flag`]: the first signal sets it, and the run ends after the
//! step under way with its recording finished and valid; a second signal, or a signal to any
//! other command, removes every staged output of the process and exits with 130.

use std::sync::atomic::{AtomicBool, Ordering};

static STOP: AtomicBool = AtomicBool::new(false);
static STOPPABLE: AtomicBool = AtomicBool::new(false);

/// Install the handler (once, at start).
pub fn install() {
    let _ = ctrlc::set_handler(|| {
        if STOPPABLE.load(Ordering::SeqCst) && !STOP.swap(true, Ordering::SeqCst) {
            eprintln!("\nstopping after this step: the outputs will hold what ran (a second signal aborts)");
            return;
        }
        let n = dvrk_kin::atomic::remove_all_staged();
        eprintln!("\ninterrupted: {n} unfinished output(s) removed, nothing written");
        std::process::exit(130);
    });
}

/// The flag a stoppable command polls; asking for it makes the first signal stop, not abort.
pub fn stop_flag() -> &'static AtomicBool {
    STOPPABLE.store(true, Ordering::SeqCst);
    &STOP
}
