//! What the live view publishes, as JSON with a JSON schema (Foxglove plots JSON channels
//! without a plug-in): the recording's `/overview` samples and the processes' health.

use recorder::{Overview, Signals};
use serde_json::{json, Map, Value};

/// Topic of the decimated signals (the recording's `/overview`, same bins).
pub const OVERVIEW_TOPIC: &str = "/overview";
/// Topic of the plant's and controller's health reports.
pub const HEALTH_TOPIC: &str = "/health";

/// A `Signals` group as a JSON object (field names carry the units).
fn signals(s: &Signals) -> Value {
    let map: Map<String, Value> = Signals::FIELDS
        .iter()
        .zip(s.values())
        .map(|(k, v)| ((*k).to_owned(), json!(v)))
        .collect();
    Value::Object(map)
}

/// One overview sample: the bin starting at `t_ns` of run time.
pub fn overview(t_ns: u64, o: &Overview) -> Vec<u8> {
    json!({
        "time_s": t_ns as f64 * 1e-9,
        "ticks": o.ticks,
        "min": signals(&o.min),
        "max": signals(&o.max),
        "mean": signals(&o.mean),
    })
    .to_string()
    .into_bytes()
}

/// JSON schema of [`overview`].
pub fn overview_schema() -> Vec<u8> {
    let group: Map<String, Value> = Signals::FIELDS
        .iter()
        .map(|k| ((*k).to_owned(), json!({"type": "number"})))
        .collect();
    let group = json!({"type": "object", "properties": group});
    json!({
        "title": "fts_servo overview: min, max and mean of the main signals per 1 ms of run (SI units)",
        "type": "object",
        "properties": {
            "time_s": {"type": "number", "description": "start of the bin, s of run time"},
            "ticks": {"type": "integer", "description": "servo ticks in the bin"},
            "min": group, "max": group, "mean": group,
        }
    })
    .to_string()
    .into_bytes()
}

/// One health report (plant or controller).
pub fn health(h: &daq_io::Health) -> Vec<u8> {
    let role = match h.role {
        daq_io::contract::role::PLANT => "plant",
        daq_io::contract::role::CONTROLLER => "controller",
        _ => "other",
    };
    let latency = |l: &daq_io::Latency| json!({"count": l.count, "p50_s": l.p50_ns as f64 * 1e-9, "p99_s": l.p99_ns as f64 * 1e-9, "max_s": l.max_ns as f64 * 1e-9});
    json!({
        "role": role,
        "state": h.state,
        "ticks": h.ticks,
        "overruns": h.overruns,
        "faults": h.faults,
        "wall_s": h.wall_s,
        "round_trip": latency(&h.latency),
        "lateness": latency(&h.lateness),
        "execution": latency(&h.execution),
    })
    .to_string()
    .into_bytes()
}

/// JSON schema of [`health`].
pub fn health_schema() -> Vec<u8> {
    json!({
        "title": "fts_servo process health (times in s)",
        "type": "object",
        "properties": {
            "role": {"type": "string"}, "state": {"type": "integer"},
            "ticks": {"type": "integer"}, "overruns": {"type": "integer"},
            "faults": {"type": "integer"}, "wall_s": {"type": "number"},
        }
    })
    .to_string()
    .into_bytes()
}
