//! Integration tests of the `dvrk` workspace: one binary, one module per concern.

mod util;

mod bad_input;
mod cli;
mod dvrk_files;
mod fuzz;
mod gc;
mod kinematics;
mod outputs;
mod paper_tables;
mod quickstart;
