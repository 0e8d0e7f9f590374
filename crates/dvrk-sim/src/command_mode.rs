//! The drive mode a command puts a joint in: a position command (servo or move, from `dvrk
//! serve`'s topics or its teleoperation) takes a joint out of effort mode.

use crate::control::Mode;
use crate::error::Result;
use crate::Sim;

/// A position command (servo or move) takes joint `i` back from effort mode (`servo_jf`, a
/// disabled arm) to the mode it started in, `modes[i]`.
pub(crate) fn leave_effort(sim: &mut Sim, i: usize, modes: &[Mode]) -> Result<()> {
    if sim.actuator(i)?.mode == Mode::Effort {
        sim.set_mode(i, modes[i])?;
    }
    Ok(())
}
