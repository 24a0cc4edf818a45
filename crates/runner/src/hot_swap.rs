//! Deploying a controller into a running loop (`servo ctl load`). A loader thread beside the
//! ticking one parses the file, builds the controller for the run's configuration, checks what
//! it was made for and the new closed loop's stability on the run's model, and hands it back
//! ready; the ticking thread only copies the request's bytes into a buffer it owns, moves the
//! prepared controller into the loop ([`crate::servo_loop::ServoLoop::hand_over`]) and sends
//! the replaced one back to be dropped — no allocation, no lock, no parsing while ticking.
//! The loader also republishes each request it takes up on `controller_loaded` for the
//! recorder: this process lives as long as the run, its requester may not.

use crate::config::{ConfigError, ControllerConfig, ControllerKind, RunConfig};
use crate::controller::Controller;
use crate::error::RunError;
use crate::gain_range::{gain_range, GainRange};
use crate::plan::Plan;
use daq_io::contract::{ack_status, ControllerLoad, MAX_LOAD_BYTES};
use daq_io::ipc::{leaf, Endpoint};
use std::path::PathBuf;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TryRecvError, TrySendError};

/// The name a loaded state-space file takes in messages and in the run's inputs.
pub const LOADED_FILE: &str = "controller loaded by servo ctl load";

/// A controller ready to take the loop, or why not.
// Moved by value: a box would be freed on the ticking thread when the controller leaves it.
#[allow(clippy::large_enum_variant)]
pub enum Prepared {
    /// Built and checked.
    Ready {
        /// The request.
        id: u64,
        /// The controller, in its initial state.
        controller: Controller,
        /// The gain scales it stays stable under.
        gains: GainRange,
        /// The spectral radius of the new sampled closed loop.
        spectral_radius: f64,
    },
    /// Refused.
    Refused {
        /// The request.
        id: u64,
        /// One of [`ack_status`]: `REFUSED_INVALID`, `REFUSED_PROVENANCE`, `REFUSED_MARGIN`.
        status: u32,
        /// The new loop's spectral radius when it was unstable (NaN otherwise).
        spectral_radius: f64,
    },
}

// Moved by value, for the same reason as `Prepared`.
#[allow(clippy::large_enum_variant)]
enum Job {
    Load(u64, Vec<u8>),
    Drop(Controller),
}

/// The loader thread and the ticking thread's ends of its channels.
pub struct Loader {
    jobs: SyncSender<Job>,
    results: Receiver<(Prepared, Vec<u8>)>,
    /// The request buffer, while it is not with the loader.
    spare: Option<Vec<u8>>,
}

impl Loader {
    /// Starts the loader thread for the run of `plan` on run `prefix` (the plan's
    /// configuration and model are what a loaded controller is built for and checked
    /// against).
    pub fn start(plan: &Plan, prefix: &str) -> Self {
        let (jobs, inbox) = sync_channel::<Job>(4);
        let (outbox, results) = sync_channel(1);
        let plan = plan.clone();
        let prefix = prefix.to_owned();
        std::thread::Builder::new()
            .name("controller-loader".into())
            .spawn(move || {
                // The node and publisher live in this thread (iceoryx2 ports stay on theirs).
                let republish = Endpoint::open(&prefix, "controller-loader")
                    .and_then(|ep| {
                        let p = ep.publisher::<ControllerLoad>(leaf::CONTROLLER_LOADED)?;
                        Ok((ep, p))
                    })
                    .inspect_err(|e| {
                        eprintln!("servo controller: loads will not be recorded: {e}");
                    })
                    .ok();
                while let Ok(job) = inbox.recv() {
                    if let Job::Load(id, buf) = job {
                        if let (Some((_, p)), Some(load)) =
                            (&republish, ControllerLoad::new(id, &buf))
                        {
                            daq_io::ipc::send(p, load);
                        }
                        let prepared = prepare(&plan, id, &buf);
                        if outbox.send((prepared, buf)).is_err() {
                            return;
                        }
                    }
                    // A Job::Drop is dropped here, off the ticking thread.
                }
            })
            .expect("a thread for the controller loader");
        Loader {
            jobs,
            results,
            spare: Some(Vec::with_capacity(MAX_LOAD_BYTES)),
        }
    }

    /// On the ticking thread: hands request `id`'s `file` to the loader (a copy into the
    /// buffer this side owns; no allocation). False while a previous request is in work.
    pub fn submit(&mut self, id: u64, file: &[u8]) -> bool {
        let Some(mut buf) = self.spare.take() else {
            return false;
        };
        buf.clear();
        buf.extend_from_slice(&file[..file.len().min(MAX_LOAD_BYTES)]);
        match self.jobs.try_send(Job::Load(id, buf)) {
            Ok(()) => true,
            Err(TrySendError::Full(job) | TrySendError::Disconnected(job)) => {
                if let Job::Load(_, buf) = job {
                    self.spare = Some(buf);
                }
                false
            }
        }
    }

    /// On the ticking thread: the result of the request in work, once ready.
    pub fn poll(&mut self) -> Option<Prepared> {
        match self.results.try_recv() {
            Ok((prepared, buf)) => {
                self.spare = Some(buf);
                Some(prepared)
            }
            Err(TryRecvError::Empty | TryRecvError::Disconnected) => None,
        }
    }

    /// On the ticking thread: drops `controller` on the loader thread. If the loader cannot
    /// take it now, it is handed back (the caller keeps it and retries later).
    pub fn dispose(&mut self, controller: Controller) -> Option<Controller> {
        match self.jobs.try_send(Job::Drop(controller)) {
            Err(TrySendError::Full(Job::Drop(c)) | TrySendError::Disconnected(Job::Drop(c))) => {
                Some(c)
            }
            // Sent (a Load cannot come back from sending a Drop).
            _ => None,
        }
    }
}

/// Parses, builds and checks request `id`'s `file` for the run of `plan`: a state-space
/// controller file (as `servo synth` writes it), or a config fragment whose `[controller]`
/// table is taken (as `servo tune` writes it). Refusals are printed with their reason.
fn prepare(plan: &Plan, id: u64, file: &[u8]) -> Prepared {
    let refused = |status: u32, spectral_radius: f64, why: &dyn std::fmt::Display| {
        eprintln!("servo controller: load {id} refused: {why}");
        Prepared::Refused {
            id,
            status,
            spectral_radius,
        }
    };
    let built = plan_after_load(plan, file).and_then(|p| gain_range(&p).map(|g| (p, g)));
    match built {
        Ok((p, _)) if reference_path_differs(plan, &p) => refused(
            ack_status::REFUSED_INVALID,
            f64::NAN,
            &format!(
                "the file changes the reference path (feedforward {:?} → {:?}, smoothing {} → {} Hz): \
                 a load swaps the feedback controller only — restart the run for another feedforward",
                plan.config.controller.feedforward,
                p.config.controller.feedforward,
                plan.config.controller.smoothing_hz,
                p.config.controller.smoothing_hz
            ),
        ),
        Ok((p, gains)) => {
            let spectral_radius = p.check_stable().unwrap_or(f64::NAN);
            Prepared::Ready {
                id,
                controller: p.controller,
                gains,
                spectral_radius,
            }
        }
        Err(RunError::Unstable { radius, .. }) => refused(
            ack_status::REFUSED_MARGIN,
            radius,
            &"the new closed loop is unstable",
        ),
        Err(e) if made_for_mismatch(&e) => refused(ack_status::REFUSED_PROVENANCE, f64::NAN, &e),
        Err(e) => refused(ack_status::REFUSED_INVALID, f64::NAN, &e),
    }
}

/// Whether the run of `after` shapes the reference differently from the run of `plan`
/// (feedforward, its smoothing): the preview window those need is sized when a run starts, and
/// a swap replaces the feedback controller only — a changed feedforward would be silently
/// ignored, so it is refused.
fn reference_path_differs(plan: &Plan, after: &Plan) -> bool {
    let (a, b) = (&plan.config.controller, &after.config.controller);
    a.feedforward != b.feedforward || a.smoothing_hz != b.smoothing_hz
}

/// Whether `e` refuses a controller made for another plant or rate.
fn made_for_mismatch(e: &RunError) -> bool {
    matches!(e, RunError::Config(ConfigError::Invalid { key, .. })
        if key == "made_for" || key.ends_with(".made_for"))
}

/// The run of `plan` with the controller `file` describes — the loop a `servo ctl load` of
/// it runs after the swap: a state-space controller file (as `servo synth` writes it), or a
/// config fragment whose `[controller]` table is taken (as `servo tune` writes it). Built and
/// checked as any run (stability, made-for), nothing read from disk; a file that is not UTF-8
/// TOML of either kind is a parse error naming [`LOADED_FILE`].
pub fn plan_after_load(plan: &Plan, file: &[u8]) -> Result<Plan, RunError> {
    let parse = |message: String| {
        RunError::from(ConfigError::Parse {
            path: PathBuf::from(LOADED_FILE),
            message,
        })
    };
    let text = std::str::from_utf8(file).map_err(|e| parse(e.to_string()))?;
    let table: toml::Table = toml::from_str(text).map_err(|e| parse(e.to_string()))?;
    let (controller, bytes) = if let Some(fragment) = table.get("controller") {
        // Whether the fragment sets the reference path (a tuning fragment holds gains only).
        let has = |key: &str| fragment.get(key).is_some();
        let (sets_feedforward, sets_smoothing) = (has("feedforward"), has("smoothing_hz"));
        let config: RunConfig = table.try_into().map_err(|e| parse(e.to_string()))?;
        if config.controller.kind == ControllerKind::Ss {
            return Err(parse(
                "a [controller] fragment of kind ss names a file: load the file".into(),
            ));
        }
        // The reference path is the run's unless the fragment says otherwise.
        let running = &plan.config.controller;
        let controller = ControllerConfig {
            feedforward: if sets_feedforward {
                config.controller.feedforward
            } else {
                running.feedforward
            },
            smoothing_hz: if sets_smoothing {
                config.controller.smoothing_hz
            } else {
                running.smoothing_hz
            },
            ..config.controller
        };
        (controller, None)
    } else {
        let controller = ControllerConfig {
            kind: ControllerKind::Ss,
            ss_file: Some(PathBuf::from(LOADED_FILE)),
            ..plan.config.controller.clone()
        };
        (controller, Some(file.to_vec()))
    };
    plan.with_controller_file(controller, bytes)
}
