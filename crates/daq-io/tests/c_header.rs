//! `include/fts_servo_contract.h` against the Rust contract: a C file of `_Static_assert`s,
//! generated here from the compiler's own sizes and offsets ([`daq_io::layout::LAYOUTS`]) and
//! the flag, command and status constants, must compile (`cc -std=c11 -Werror`). A header
//! that drifts from the Rust types fails to compile and names the field.

use daq_io::contract::{ack_status, command, role, state, stop_cause, MAX_LOAD_BYTES};
use daq_io::{flags, layout::LAYOUTS, BLOCK_TICKS, CONTRACT_VERSION};
use std::fmt::Write;
use std::process::Command;

/// Every constant the header defines, with the Rust value it must equal.
fn constants() -> Vec<(&'static str, u64)> {
    let f = |n, v: u32| (n, u64::from(v));
    vec![
        ("FTS_SERVO_CONTRACT_VERSION", u64::from(CONTRACT_VERSION)),
        ("FTS_SERVO_BLOCK_TICKS", BLOCK_TICKS as u64),
        ("FTS_SERVO_MAX_LOAD_BYTES", MAX_LOAD_BYTES as u64),
        f("FTS_FLAG_GAP_CLIPPED", flags::GAP_CLIPPED),
        f("FTS_FLAG_ACCEL_CLIPPED", flags::ACCEL_CLIPPED),
        f("FTS_FLAG_DAC_CLIPPED", flags::DAC_CLIPPED),
        f("FTS_FLAG_COMMAND_NOT_FINITE", flags::COMMAND_NOT_FINITE),
        f("FTS_FLAG_SATURATED", flags::SATURATED),
        f("FTS_FLAG_TRIPPED", flags::TRIPPED),
        f("FTS_FLAG_TRIP_FOLLOWING_ERROR", flags::TRIP_FOLLOWING_ERROR),
        f("FTS_FLAG_TRIP_SENSOR_RANGE", flags::TRIP_SENSOR_RANGE),
        f("FTS_FLAG_TRIP_SATURATION", flags::TRIP_SATURATION),
        f("FTS_FLAG_TRIP_NOT_FINITE", flags::TRIP_NOT_FINITE),
        f("FTS_FLAG_TRIP_REFERENCE_FAULT", flags::TRIP_REFERENCE_FAULT),
        f("FTS_FLAG_END", flags::END),
        f("FTS_FLAG_FAULT_PEER_LOST", flags::FAULT_PEER_LOST),
        f("FTS_FLAG_OVERRUN", flags::OVERRUN),
        f("FTS_FLAG_FAULT_CONTROLLER", flags::FAULT_CONTROLLER),
        f("FTS_FLAG_FAULT_OVERRUN_BUDGET", flags::FAULT_OVERRUN_BUDGET),
        f("FTS_FLAG_NO_TELEMETRY", flags::NO_TELEMETRY),
        f("FTS_FLAG_NO_TRUTH", flags::NO_TRUTH),
        f("FTS_COMMAND_STOP", command::STOP),
        f("FTS_COMMAND_SET_GAIN_SCALE", command::SET_GAIN_SCALE),
        f("FTS_COMMAND_START", command::START),
        f("FTS_COMMAND_LOAD_CONTROLLER", command::LOAD_CONTROLLER),
        f("FTS_ACK_APPLIED", ack_status::APPLIED),
        f("FTS_ACK_REFUSED_MARGIN", ack_status::REFUSED_MARGIN),
        f("FTS_ACK_REFUSED_INVALID", ack_status::REFUSED_INVALID),
        f("FTS_ACK_REFUSED_PROVENANCE", ack_status::REFUSED_PROVENANCE),
        f("FTS_ROLE_PLANT", role::PLANT),
        f("FTS_ROLE_CONTROLLER", role::CONTROLLER),
        f("FTS_ROLE_RECORDER", role::RECORDER),
        f("FTS_STATE_WAITING", state::WAITING),
        f("FTS_STATE_RUNNING", state::RUNNING),
        f("FTS_STATE_DONE", state::DONE),
        f("FTS_STATE_FAULTED", state::FAULTED),
        f("FTS_STATE_HELD_FOR_RECORDER", state::HELD_FOR_RECORDER),
        f("FTS_STOP_CAUSE_NONE", stop_cause::NONE),
        f("FTS_STOP_CAUSE_CONTROL", stop_cause::CONTROL),
        f("FTS_STOP_CAUSE_WRITE_FAILED", stop_cause::WRITE_FAILED),
        f("FTS_STOP_CAUSE_TRIPPED", stop_cause::TRIPPED),
    ]
}

/// The C assertions of every layout and constant.
fn assertions() -> String {
    let mut c = String::from(
        "#include <stddef.h>\n#include <string.h>\n#include \"fts_servo_contract.h\"\n",
    );
    for t in LAYOUTS {
        let ty = format!("fts_{}", t.name);
        let _ = writeln!(
            c,
            "_Static_assert(sizeof({ty}) == {}, \"size of {ty}\");",
            t.size
        );
        let _ = writeln!(
            c,
            "_Static_assert(_Alignof({ty}) == {}, \"alignment of {ty}\");",
            t.align
        );
        for (field, offset) in t.fields {
            let _ = writeln!(
                c,
                "_Static_assert(offsetof({ty}, {field}) == {offset}, \"offset of {ty}.{field}\");"
            );
        }
    }
    for (name, value) in constants() {
        let _ = writeln!(
            c,
            "_Static_assert({name} == {value}u, \"value of {name}\");"
        );
    }
    c.push_str(
        "int fts_type_name_is_versioned(void) { return strcmp(FTS_SERVO_TYPE_NAME(Sensor), ",
    );
    let _ = writeln!(c, "\"fts_servo::v{CONTRACT_VERSION}::Sensor\"); }}");
    c
}

#[test]
fn the_c_header_matches_every_size_offset_and_constant() {
    let include = concat!(env!("CARGO_MANIFEST_DIR"), "/../../include");
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("check.c");
    std::fs::write(&source, assertions()).unwrap();
    let out = Command::new("cc")
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-c", "-o"])
        .arg(dir.path().join("check.o"))
        .arg("-I")
        .arg(include)
        .arg(&source)
        .output()
        .expect("a C compiler (cc) — the Rust toolchain links with it");
    assert!(
        out.status.success(),
        "include/fts_servo_contract.h differs from the Rust contract:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_drifted_header_fails_the_check() {
    // The check itself can fail: the same assertions against a header with one field moved.
    let header = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../include/fts_servo_contract.h"
    ))
    .unwrap();
    let drifted = header.replacen(
        "    double gap_v;           /* gap sensor reading, V */\n    double accel_v;",
        "    double accel_v;           /* swapped */\n    double gap_v;",
        1,
    );
    assert_ne!(drifted, header, "the edit applies");
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("fts_servo_contract.h"), drifted).unwrap();
    std::fs::write(dir.path().join("check.c"), assertions()).unwrap();
    let out = Command::new("cc")
        .args(["-std=c11", "-fsyntax-only", "-I"])
        .arg(dir.path())
        .arg(dir.path().join("check.c"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("offset of fts_Sensor.gap_v"));
}
