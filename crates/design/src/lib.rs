//! # design
//!
//! Offline controller design and identification on top of [`lti`]: H2 synthesis
//! ([`h2`]), PID tuning by convex-concave programming ([`tune`], clarabel LPs), grey-box
//! identification ([`identify`]), stability margins ([`loops`]), ZPETC feedforward
//! ([`zpetc`]) and FIR feedforward from measured data ([`fir`]), repetitive control's convergence ([`repetitive`]) and three-probe spindle
//! error separation ([`spindle`], thesis Appendix D).

pub mod fir;
pub mod h2;
pub mod identify;
pub mod loops;
mod lp;
pub mod repetitive;
pub mod spindle;
pub mod tune;
pub mod zpetc;
