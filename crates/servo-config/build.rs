//! The state-space order cap of this build: `FTS_SERVO_MAX_SS_ORDER` (1–40, default 40) at
//! build time. A microcontroller that runs small controllers builds with a low cap and carries
//! only the orders it runs (flash) and the storage of the largest (RAM); a loop above the cap
//! is refused where it is loaded, naming `controller.ss`.

use std::fmt::Write as _;

/// The largest order a build can carry (the enum of orders and the image format's bound).
const LARGEST: usize = 40;
/// The build-time variable that sets the cap.
const VAR: &str = "FTS_SERVO_MAX_SS_ORDER";

fn main() {
    println!("cargo:rerun-if-env-changed={VAR}");
    let cap = match std::env::var(VAR) {
        Err(_) => LARGEST,
        Ok(text) => match text.trim().parse::<usize>() {
            Ok(n) if (1..=LARGEST).contains(&n) => n,
            _ => panic!("{VAR} = {text:?}: allowed a whole number of states in 1..={LARGEST}"),
        },
    };
    let mut orders = String::from("state_space_orders! {\n");
    for n in 1..=cap {
        let _ = writeln!(orders, "    {n},");
    }
    orders.push_str("}\n");
    let out = std::path::PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    std::fs::write(out.join("orders.rs"), orders).expect("OUT_DIR is writable");
    std::fs::write(out.join("max_order.rs"), format!("{cap}\n")).expect("OUT_DIR is writable");
}
