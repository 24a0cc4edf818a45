//! # runner
//!
//! One closed-loop run as a library: the configuration (TOML, thesis defaults, located
//! errors), the controller from servo-core, the simulated stage from plant-sim, a pre-run
//! stability check on the exact sampled loop, the recording (MCAP) and the summary. The
//! `servo` binary is a thin shell over this; a DAQ daemon or a notebook can call it too.
//!
//! ```no_run
//! use runner::{config::Loaded, run::{run, RunOptions}};
//! use std::sync::atomic::AtomicBool;
//! let cfg = Loaded::default(); // thesis prototype, Chapter 7 PID, hold position, 1 s
//! let stop = AtomicBool::new(false);
//! let summary = run(&cfg, RunOptions { out: None, stop: &stop, progress: &mut |_, _| {} })?;
//! println!("{summary}");
//! # Ok::<(), runner::run::RunError>(())
//! ```

pub mod analysis;
pub mod config;
pub mod controller;
pub mod feedforward;
pub mod form;
pub mod frf;
pub mod hil;
pub mod identify;
pub mod intermittent;
pub mod machine;
pub mod preview;
pub mod report;
pub mod run;
pub mod servo_loop;
pub mod spindle;
pub mod stiffness;
pub mod summary;
pub mod sweep;
pub mod synth;
pub mod tune;
