//! libfts_fmu driven in process through its FMI functions, against the simulator's and the
//! runtime's own calls.

mod support;
mod units;
