//! # runner
//!
//! The closed-loop runtime as a library, built once from a resolved [`Plan`]: the
//! configuration and the simulated stage it describes (the `run-config` crate), the controller
//! from servo-core, a pre-run stability check on the
//! exact sampled loop, the recording (MCAP) and the summary — in one process ([`run`]) or as
//! the plant, controller and recorder processes of a HIL run ([`hil`]), and a recording re-run
//! from what it holds ([`replay`]). The offline studies
//! live in the `studies` crate; the `servo` binary is a thin shell over both.
//!
//! ```no_run
//! use run_config::Loaded;
//! use runner::{run::{run, RunOptions}, stop::StopRequest, Plan};
//! // thesis prototype, Chapter 7 PID, hold position, 1 s
//! let plan = Plan::new(&Loaded::default())?;
//! let stop = StopRequest::new();
//! let opts = RunOptions { out: None, stop: &stop, progress: &mut |_, _| {}, digest: false };
//! let summary = run(&plan, opts)?;
//! println!("{summary}");
//! # Ok::<(), runner::RunError>(())
//! ```

pub mod deploy;
mod error;
pub mod gain_range;
pub mod hil;
pub mod hot_swap;
pub mod join;
pub mod machining;
pub mod operator_log;
pub mod pil;
pub mod plan;
pub mod plan_loop;
mod recorded_deployment;
pub mod recording;
pub mod remote_plant;
pub mod repetitive;
pub mod replay;
pub mod run;
mod run_input;
pub mod schema;
pub mod stall;
pub mod stop;
pub mod summary;

pub use error::RunError;
pub use plan::Plan;
pub use plan_loop::PlanLoop;
