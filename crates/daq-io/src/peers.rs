//! Who is on a run: every process of a run names its iceoryx2 node
//! `fts-servo/v<contract version>/<prefix>/<role>`, so a process joining a run can see the live
//! processes already there — to refuse a prefix a live run holds (naming its pid and age), and a
//! peer that speaks another contract version (naming both versions).

use crate::contract::CONTRACT_VERSION;
use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;

/// Roles of which a run has exactly one: a second one on a prefix is a second run (`run` is
/// the `servo run --hil` orchestrator).
pub const EXCLUSIVE_ROLES: [&str; 4] = ["run", "plant", "controller", "recorder"];

/// The node name of `role` in run `prefix` under this contract version.
pub fn node_name(prefix: &str, role: &str) -> String {
    format!("fts-servo/v{CONTRACT_VERSION}/{prefix}/{role}")
}

/// A live process of a run, as its node name and details say.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Peer {
    /// Its role (`plant`, `controller`, `recorder`, `ctl-<pid>`, …).
    pub role: String,
    /// The contract version it speaks.
    pub version: u32,
    /// Its process id.
    pub pid: i32,
}

impl Peer {
    /// "its plant (pid 1234, started 5.2 s ago)".
    pub fn describe(&self) -> String {
        let who = match self.role.as_str() {
            "run" => "its `servo run --hil`".to_string(),
            role => format!("its {role}"),
        };
        let pid = self.pid;
        match started_s_ago(pid) {
            Some(age) => format!("{who} (pid {pid}, started {age:.1} s ago)"),
            None => format!("{who} (pid {pid})"),
        }
    }
}

/// Parses `fts-servo/v<N>/<prefix>/<role>` into (version, prefix, role).
fn parse(name: &str) -> Option<(u32, &str, &str)> {
    let rest = name.strip_prefix("fts-servo/v")?;
    let (version, rest) = rest.split_once('/')?;
    let (prefix, role) = rest.split_once('/')?;
    Some((version.parse().ok()?, prefix, role))
}

/// The live processes of run `prefix` (any contract version), except the node `own` (this
/// process's, when it has one). Dead nodes are not listed (they are cleaned when a process
/// joins).
pub fn live_peers(prefix: &str, own: Option<&iceoryx2::identifiers::UniqueNodeId>) -> Vec<Peer> {
    let mut peers = Vec::new();
    let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Alive(view) = state {
            if own.is_some_and(|id| id == view.id()) {
                return CallbackProgression::Continue;
            }
            if let Some(details) = view.details() {
                if let Some((version, p, role)) = parse(details.name().as_str()) {
                    if p == prefix {
                        peers.push(Peer {
                            role: role.to_owned(),
                            version,
                            pid: details.process_id().value(),
                        });
                    }
                }
            }
        }
        CallbackProgression::Continue
    });
    peers
}

/// Why `role` may not join run `prefix` given its live `peers`: a peer of another contract
/// version, or another process in the same exclusive role (a second run on the prefix).
pub fn refusal(prefix: &str, role: &str, peers: &[Peer]) -> Option<String> {
    if let Some(p) = peers.iter().find(|p| p.version != CONTRACT_VERSION) {
        return Some(format!(
            "contract mismatch on run prefix {prefix:?}: {} speaks fts-servo contract v{}, this {role} v{CONTRACT_VERSION}; run the same fts-servo version (or a DAQ daemon built against include/fts_servo_contract.h v{CONTRACT_VERSION})",
            p.describe(),
            p.version
        ));
    }
    if EXCLUSIVE_ROLES.contains(&role) {
        if let Some(p) = peers.iter().find(|p| p.role == role) {
            return Some(format!(
                "run prefix {prefix:?} is in use by a live run: {} holds it; choose another run prefix or stop that run (a STOP on its control plane)",
                p.describe()
            ));
        }
    }
    None
}

/// A fresh random identity (nonzero) for a run or a control-plane request: the standard
/// library's per-process random hash keys, mixed with the pid and the clock.
pub fn random_id() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u32(std::process::id());
    if let Ok(t) = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH) {
        h.write_u128(t.as_nanos());
    }
    h.finish() | 1
}

/// Seconds since process `pid` started (from `/proc`: its start in clock ticks after boot,
/// at the kernel's fixed 100 Hz USER_HZ, against the uptime).
fn started_s_ago(pid: i32) -> Option<f64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the parenthesised command name; starttime is field 22 (index 19 here).
    let after = stat.rsplit_once(')')?.1;
    let start_ticks: f64 = after.split_whitespace().nth(19)?.parse().ok()?;
    let uptime: f64 = std::fs::read_to_string("/proc/uptime")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    Some((uptime - start_ticks / 100.0).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_names_round_trip() {
        let n = node_name("bench-1", "plant");
        assert_eq!(n, format!("fts-servo/v{CONTRACT_VERSION}/bench-1/plant"));
        assert_eq!(parse(&n), Some((CONTRACT_VERSION, "bench-1", "plant")));
        assert_eq!(parse("fts-servo-bench-plant"), None);
        assert_eq!(parse("fts-servo/vX/a/b"), None);
    }

    #[test]
    fn refusals_name_the_live_run_and_both_versions() {
        let me = std::process::id() as i32;
        let plant = |version| Peer {
            role: "plant".into(),
            version,
            pid: me,
        };
        let e = refusal("p", "plant", &[plant(CONTRACT_VERSION)]).unwrap();
        assert!(
            e.contains("in use") && e.contains(&format!("pid {me}")) && e.contains("s ago"),
            "{e}"
        );
        assert_eq!(refusal("p", "controller", &[plant(CONTRACT_VERSION)]), None);
        assert_eq!(refusal("p", "ctl-1", &[plant(CONTRACT_VERSION)]), None);
        let e = refusal("p", "controller", &[plant(2)]).unwrap();
        assert!(
            e.contains("contract v2") && e.contains(&format!("v{CONTRACT_VERSION}")),
            "{e}"
        );
        // This process started a moment ago.
        assert!(started_s_ago(me).unwrap() < 3600.0);
    }
}
