//! One module per `servo` subcommand: its flags (clap) and what it does with the libraries.

pub mod budget;
pub mod completions;
pub mod config;
pub mod ctl;
pub mod deploy;
pub mod export;
pub mod fit;
pub mod frf;
pub mod hil;
pub mod identify;
pub mod inspect;
pub mod intermittent;
pub mod latency;
pub mod machine;
pub mod replay;
pub mod run;
pub mod run_hil;
pub mod spectrum;
pub mod spindle_errors;
pub mod stiffness;
pub mod study;
pub mod synth;
pub mod thesis;
pub mod toolpath;
pub mod tune;
pub mod view;
