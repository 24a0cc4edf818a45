//! Spectrum analysis of a recorded run (thesis §5.7.4, Fig 5-15/5-16): Welch PSD and CAS of
//! the following error, the control output and — where the recording carries the simulator's
//! truth — the true tool error, beside the error budget's prediction for the recorded
//! configuration, with the difference per decade band.
//!
//! The recording streams through in constant memory (one Welch segment per signal). Only the
//! steady part counts: from the run's settle time (or a chosen start) to its end (or a chosen
//! end), or to a trip. The prediction can be for another controller than the recorded one —
//! the one `servo ctl load` swapped in, for the part of the run after the swap.

use crate::StudyError;
use loop_model::closed_loop::{output, SOURCES};
use lti::spectral::{Psd, Welch, WelchConfig};
use lti::welch_statistics::{expected_welch, BandScatter};
use recorder::Frame;
use run_config::MadeFor;
use runner::operator_log::Swap;
use runner::recording::{FrameSink, RunHeader};
use runner::RunError;
use serde::Serialize;

/// Lowest and highest frequency resolution accepted, Hz.
pub const RESOLUTION_RANGE_HZ: (f64, f64) = (0.1, 1000.0);

/// The first Welch bin the band comparison uses (the segment's mean removal changes bins 0 and
/// 1, which the expectation does not model, and a recording's slow drift lies within the Hann
/// window's main lobe around DC).
pub const COMPARED_FROM_BIN: usize = 4;

/// The three signals analysed, in their recorded units.
#[derive(Debug, Clone, Serialize)]
pub struct Signals<T> {
    /// Following error `r − measured`, m.
    pub following_error_m: T,
    /// True tool error `tool − r`, m (simulator truth; absent for a hardware recording).
    pub true_error_m: Option<T>,
    /// Control output (DAC command), V.
    pub control_v: T,
}

/// RMS of each signal in one frequency band: recorded, predicted, difference.
#[derive(Debug, Clone, Serialize)]
pub struct BandRms {
    /// Recorded RMS in the band (signal unit).
    pub recorded: f64,
    /// The budget's RMS in the band, on the same bins.
    pub predicted: Option<f64>,
    /// `recorded / predicted − 1`, %.
    pub difference_percent: Option<f64>,
    /// How far the recorded RMS strays from the truth by chance alone, 1σ, % (the Welch
    /// average's scatter for Gaussian noise of the predicted spectrum's shape, or the
    /// recorded one's without a prediction): a difference of a few of these is noise, not a
    /// model error.
    pub chance_percent: f64,
}

/// One decade band (the first cut at bin [`COMPARED_FROM_BIN`], the last at Nyquist).
#[derive(Debug, Clone, Serialize)]
pub struct Band {
    /// Lower edge, Hz (inclusive).
    pub from_hz: f64,
    /// Upper edge, Hz (exclusive; Nyquist inclusive for the last band).
    pub to_hz: f64,
    /// Welch bins in the band.
    pub bins: usize,
    /// Per signal.
    pub rms: Signals<BandRms>,
}

/// The spectra of a recording and the budget's prediction for it.
#[derive(Debug, Clone, Serialize)]
pub struct Spectrum {
    /// The plant and rate of the recorded configuration.
    pub made_for: MadeFor,
    /// The recorded controller's description.
    pub controller: String,
    /// Sample rate of the analysed telemetry, Hz (servo rate / recording decimation).
    pub sample_rate_hz: f64,
    /// Bin spacing, Hz.
    pub resolution_hz: f64,
    /// Samples analysed (after the settle time, before any trip).
    pub samples: u64,
    /// Welch segments averaged (Hann, 50 % overlap): each bin's relative standard deviation is
    /// about 1/√segments.
    pub segments: usize,
    /// Analysis start, s of run time.
    pub from_s: f64,
    /// The controller the prediction is for (the one in the loop at the window's start, or
    /// the one given).
    pub predicted_with: Option<String>,
    /// When controllers were swapped into the run (`servo ctl load`), s of run time.
    pub swapped_at_s: Vec<f64>,
    /// A caveat on the window (a swap inside it: one controller's budget cannot predict it).
    pub window_note: Option<String>,
    /// Bin frequencies, Hz (DC left out).
    pub freq_hz: Vec<f64>,
    /// Recorded one-sided PSDs (signal unit²/Hz).
    pub recorded_psd: Signals<Vec<f64>>,
    /// What the Welch estimate of the budget's noise should read on the same bins (the budget's
    /// PSD for the recorded configuration averaged over the window's kernel; noise sources
    /// only: a scenario's reference adds tracking error that is not in it).
    pub predicted_psd: Option<Signals<Vec<f64>>>,
    /// Why there is no prediction, when there is none.
    pub prediction_note: Option<String>,
    /// Per decade band.
    pub bands: Vec<Band>,
    /// Whole band ([`COMPARED_FROM_BIN`] bins to Nyquist).
    pub total: Signals<BandRms>,
}

/// What part of a recording to analyse, how finely, and with which controller to predict it.
#[derive(Debug, Clone)]
pub struct SpectrumOptions {
    /// Bin spacing, Hz (within [`RESOLUTION_RANGE_HZ`]).
    pub resolution_hz: f64,
    /// Analysis start, s of run time (None: the run's settle time).
    pub from_s: Option<f64>,
    /// Analysis end, s of run time (None: the end of the recording).
    pub to_s: Option<f64>,
    /// Predict with this controller instead of the one in the loop at the window's start.
    pub controller: Option<run_config::ControllerConfig>,
    /// The controllers swapped into the run (`servo ctl load`), as its recording keeps them
    /// ([`runner::operator_log::OperatorLog::read`]): the default window starts after the last one, and the
    /// prediction is for the controller in the loop at the window's start.
    pub swaps: Vec<Swap>,
}

/// The Welch estimates filled as the frames stream past.
struct Estimates {
    from_ns: u64,
    to_ns: u64,
    /// The Welch settings (Hann, 50 % overlap, segments of `fs / resolution`).
    welch: WelchConfig,
    /// Time of the last frame read, ns of run time.
    last_ns: u64,
    fs_hz: f64,
    following: Welch,
    true_error: Welch,
    control: Welch,
    truth_seen: bool,
    samples: u64,
    tripped: bool,
    /// Time of the last frame in the window, ns of run time.
    previous_ns: Option<u64>,
    /// Ticks the window lacks (time gaps, frames without telemetry) and the first such time
    /// in s.
    lost: Option<(u64, f64)>,
}

/// Reads the frames of a recording into spectra ([`FrameSink`] for
/// [`runner::recording::inspect_with`]); [`SpectrumSink::finish`] gives the result.
pub struct SpectrumSink {
    options: SpectrumOptions,
    header: Option<(MadeFor, String, f64)>,
    swapped_at_s: Vec<f64>,
    window_note: Option<String>,
    prediction: Result<runner::Plan, String>,
    estimates: Option<Estimates>,
}

impl SpectrumSink {
    /// Spectra as `options` ask.
    pub fn new(options: SpectrumOptions) -> Self {
        SpectrumSink {
            options,
            header: None,
            swapped_at_s: Vec::new(),
            window_note: None,
            prediction: Err("the recording has no header".into()),
            estimates: None,
        }
    }
}

impl FrameSink for SpectrumSink {
    fn header(&mut self, h: &RunHeader) -> Result<(), RunError> {
        let config = &h.loaded.config;
        let every = h.every.get();
        let fs_hz = config.plant.timing.servo_rate_hz / f64::from(every);
        let o = &self.options;
        let settings = WelchConfig::hann((fs_hz / o.resolution_hz).round().max(2.0) as usize);
        let welch = || {
            Welch::new(fs_hz, &settings).map_err(|e| {
                h.loaded
                    .origin
                    .invalid("resolution_hz", o.resolution_hz, &e.to_string())
            })
        };
        // The window is checked against the recording's own length when it has been read (a
        // plant process, not the configured duration, decides how long a HIL run lasts).
        // Its default start: the settle time after the start, or after the last swap.
        let period_s = 1.0 / config.plant.timing.servo_rate_hz;
        let swap_s = |w: &Swap| w.tick as f64 * period_s;
        let from_s = o
            .from_s
            .unwrap_or_else(|| config.run.settle() + o.swaps.last().map_or(0.0, swap_s));
        let at = run_config::Origin::default();
        if !(from_s >= 0.0 && from_s.is_finite()) {
            return Err(at.invalid("from_s", from_s, "≥ 0 s").into());
        }
        if let Some(to_s) = o.to_s.filter(|&t| !(t > from_s && t.is_finite())) {
            return Err(at
                .invalid("to_s", to_s, &format!("> {from_s} s (from_s)"))
                .into());
        }
        self.estimates = Some(Estimates {
            from_ns: (from_s * 1e9).round() as u64,
            to_ns: o.to_s.map_or(u64::MAX, |t| (t * 1e9).round() as u64),
            welch: settings,
            last_ns: 0,
            fs_hz,
            following: welch()?,
            true_error: welch()?,
            control: welch()?,
            truth_seen: false,
            samples: 0,
            tripped: false,
            previous_ns: None,
            lost: None,
        });
        self.header = Some((
            run_config::made_for_plant(&config.plant),
            h.controller.clone(),
            from_s,
        ));
        // The controller in the loop at the window's start, and any swap inside the window.
        let running = o.swaps.iter().rev().find(|w| swap_s(w) <= from_s);
        let to_s = o.to_s.unwrap_or(f64::INFINITY);
        let moving = !matches!(config.scenario, run_config::Scenario::Hold);
        let window_note = o
            .swaps
            .iter()
            .find(|w| swap_s(w) > from_s && swap_s(w) < to_s)
            .map(|w| {
                format!(
                    "a controller was swapped in at {:.3} s, inside the window: the budget is \
                     for the one before it (choose from_s / to_s on one side)",
                    swap_s(w)
                )
            })
            .or_else(|| {
                (!h.reading_used && moving).then(|| {
                    "recorded before contract v6: its following error pairs each tick's \
                     reference with the next reading, so a moving reference adds a tick of its \
                     motion to it (the noise is unaffected)"
                        .to_owned()
                })
            });
        let swapped_at_s = o.swaps.iter().map(swap_s).collect();
        self.prediction = if every > 1 {
            Err(format!(
                "recorded every {every} ticks without an anti-alias filter: the spectrum above \
                 {:.0} Hz is folded into it; record at full rate (--record-every 1) to compare",
                fs_hz / 2.0
            ))
        } else {
            match (&o.controller, running) {
                (Some(c), _) => h.replan(run_config::RunConfig {
                    controller: c.clone(),
                    ..config.clone()
                }),
                (None, Some(w)) => h
                    .plan()
                    .and_then(|p| runner::hot_swap::plan_after_load(&p, &w.file)),
                (None, None) => h.plan(),
            }
            .map_err(|e| format!("the configuration to predict with does not build: {e}"))
        };
        self.window_note = window_note;
        self.swapped_at_s = swapped_at_s;
        Ok(())
    }

    fn frame(&mut self, f: &Frame) {
        let Some(e) = &mut self.estimates else {
            return;
        };
        e.last_ns = f.time_ns;
        if f.telemetry.flags as u32 & daq_io::flags::TRIPPED != 0 {
            e.tripped = true;
        }
        if e.tripped || f.time_ns < e.from_ns || f.time_ns > e.to_ns {
            return;
        }
        // A missing tick is a step in every signal: a spectrum across it is not the loop's.
        let period_s = 1.0 / e.fs_hz;
        let skipped = e.previous_ns.map_or(0, |p| {
            ((f.time_ns.saturating_sub(p) as f64 * 1e-9 / period_s).round() as u64)
                .saturating_sub(1)
        });
        let without_telemetry = f.telemetry.flags as u32 & daq_io::flags::NO_TELEMETRY != 0;
        if skipped > 0 || without_telemetry {
            // The first missing tick: the one after the previous frame, or this one.
            let at_s = match (skipped, e.previous_ns) {
                (1.., Some(p)) => p as f64 * 1e-9 + period_s,
                _ => f.time_ns as f64 * 1e-9,
            };
            let (n, _) = e.lost.get_or_insert((0, at_s));
            *n += skipped + u64::from(without_telemetry);
        }
        e.previous_ns = Some(f.time_ns);
        e.following.push(f64::from(f.telemetry.following_error_m));
        e.control.push(f64::from(f.telemetry.control_v));
        e.true_error.push(f64::from(f.truth.true_error_m));
        e.truth_seen |= f.truth.tool_m != 0.0 || f.truth.gap_m != 0.0;
        e.samples += 1;
    }
}

impl SpectrumSink {
    /// The spectra, the prediction and the band table.
    pub fn finish(self) -> Result<Spectrum, StudyError> {
        let (Some(e), Some((made_for, controller, from_s))) = (self.estimates, self.header) else {
            return Err(lti::spectral::SpectralError::Argument("no run header was read").into());
        };
        if e.samples < e.welch.segment_len as u64 {
            let segment_s = e.welch.segment_len as f64 / e.fs_hz;
            let end_s = e.last_ns as f64 * 1e-9;
            return Err(run_config::Origin::default()
                .invalid(
                    "from_s",
                    from_s,
                    &format!(
                        "a window of at least one {segment_s} s segment before the recording's \
                         end at {end_s:.3} s{}: {} samples from there",
                        if e.tripped { " (or its trip)" } else { "" },
                        e.samples
                    ),
                )
                .into());
        }
        if let Some((ticks, at_s)) = e.lost {
            return Err(run_config::Origin::default()
                .invalid(
                    "from_s",
                    from_s,
                    &format!(
                        "a window without lost ticks: the recording lacks {ticks} tick(s) in it, \
                         the first at {at_s:.6} s (the recorder fell behind or the controller was \
                         gone; see its dropped frames), and a spectrum across them is not the \
                         loop's"
                    ),
                )
                .into());
        }
        let body = |p: Psd| p.density[1..].to_vec();
        let following = e.following.finish()?;
        let resolution_hz = following.bin_hz();
        let freq_hz = following.freq_hz[1..].to_vec();
        let recorded_psd = Signals {
            following_error_m: body(following),
            true_error_m: if e.truth_seen {
                Some(body(e.true_error.finish()?))
            } else {
                None
            },
            control_v: body(e.control.finish()?),
        };
        let predicted_with = self
            .prediction
            .as_ref()
            .ok()
            .map(|p| p.controller.description.clone());
        let (predicted_psd, prediction_note) = match self.prediction {
            Ok(plan) => {
                // What the Welch estimate of the budget's noise should read (the PSD averaged
                // over the window's kernel), not the PSD at the bin centres.
                let cl = &plan.closed_loop;
                let sources: Vec<(usize, f64)> = SOURCES
                    .iter()
                    .zip(cl.noise_variance)
                    .map(|((_, input), variance)| (*input, variance))
                    .collect();
                let [f, t, c] = expected_welch(
                    &cl.sys,
                    cl.period_s,
                    [
                        output::FOLLOWING_ERROR_M,
                        output::TRUE_ERROR_M,
                        output::CONTROL_V,
                    ],
                    &sources,
                    &e.welch,
                )?;
                (
                    Some(Signals {
                        following_error_m: f[1..].to_vec(),
                        true_error_m: e.truth_seen.then(|| t[1..].to_vec()),
                        control_v: c[1..].to_vec(),
                    }),
                    None,
                )
            }
            Err(why) => (None, Some(why)),
        };
        let nyquist = e.fs_hz / 2.0;
        let scatter = BandScatter::new(&e.welch, e.following.segments());
        // The band [lo, hi) (hi included at Nyquist): its bins and each signal's RMS.
        let band = |lo: f64, hi: f64| {
            let inside = |f: f64| f >= lo && (f < hi || (hi >= nyquist && f <= hi));
            let rms = |psd: &[f64]| {
                (freq_hz
                    .iter()
                    .zip(psd)
                    .filter(|(f, _)| inside(**f))
                    .map(|(_, d)| d)
                    .sum::<f64>()
                    * resolution_hz)
                    .sqrt()
            };
            let compare = |rec: &[f64], pred: Option<&[f64]>| {
                let recorded = rms(rec);
                let predicted = pred.map(rms);
                let shape: Vec<f64> = freq_hz
                    .iter()
                    .zip(pred.unwrap_or(rec))
                    .filter(|(f, _)| inside(**f))
                    .map(|(_, d)| *d)
                    .collect();
                // The RMS scatters half as much as the power (to first order).
                let chance = scatter.relative_std(&shape);
                BandRms {
                    recorded,
                    predicted,
                    difference_percent: predicted.map(|p| 100.0 * (recorded / p - 1.0)),
                    chance_percent: 50.0 * chance,
                }
            };
            let p = predicted_psd.as_ref();
            let rms = Signals {
                following_error_m: compare(
                    &recorded_psd.following_error_m,
                    p.map(|p| p.following_error_m.as_slice()),
                ),
                true_error_m: recorded_psd
                    .true_error_m
                    .as_ref()
                    .map(|rec| compare(rec, p.and_then(|p| p.true_error_m.as_deref()))),
                control_v: compare(&recorded_psd.control_v, p.map(|p| p.control_v.as_slice())),
            };
            Band {
                from_hz: lo,
                to_hz: hi,
                bins: freq_hz.iter().filter(|f| inside(**f)).count(),
                rms,
            }
        };
        // The Hann window's main lobe is four bins wide: the lowest bins mix in the mean and
        // the steep rise below them, so the comparison starts at the fourth.
        let first = COMPARED_FROM_BIN as f64 * resolution_hz;
        let mut edges = vec![first];
        let mut decade = libm::pow(10f64, libm::log10(first).floor() + 1.0);
        while decade < nyquist {
            edges.push(decade);
            decade *= 10.0;
        }
        edges.push(nyquist);
        // A first partial decade of a few bins says nothing on its own: it joins the next.
        if edges.len() > 2 && (edges[1] - first) / resolution_hz < COMPARED_FROM_BIN as f64 {
            edges.remove(1);
        }
        let bands: Vec<Band> = edges
            .windows(2)
            .map(|w| band(w[0], w[1]))
            .filter(|b| b.bins > 0)
            .collect();
        Ok(Spectrum {
            made_for,
            controller,
            sample_rate_hz: e.fs_hz,
            resolution_hz,
            samples: e.samples,
            segments: e.following.segments(),
            from_s,
            predicted_with,
            swapped_at_s: self.swapped_at_s,
            window_note: self.window_note,
            total: band(first, nyquist).rms,
            freq_hz,
            recorded_psd,
            predicted_psd,
            prediction_note,
            bands,
        })
    }
}
