//! The TOML forms of a loop: the deployment file (`servo deploy` writes it, a daemon's
//! `servo_runtime::Servo::from_file` reads it), and the controller files a running loop loads — a
//! `[controller]` table (as `servo tune` writes it) or a state-space file (as `servo synth`
//! writes it). Numbers are written in shortest round-trip form, so a file read back is the
//! loop that was written, bit for bit.

use super::made_for::MadeFor;
use super::origin::{ConfigError, Origin};
use crate::deployment::{
    ControllerKind, ControllerSpec, Deployment, FeedforwardSpec, FirSpec, PidGains, ReferenceSpec,
    SsMatrices, Stability, Stage, ZpetcSpec, MAX_FIR_TAPS, MAX_SS_ORDER, ZPETC_SECTIONS,
};
use crate::protection::ProtectionConfig;
use serde::{Deserialize, Serialize};
use std::fmt::Write;

/// `x` in shortest round-trip form, as TOML: plain below 1e15 and from 1e-4, scientific
/// otherwise; `inf`, `-inf`, `nan`.
pub fn num(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.into()
    } else if x == 0.0 || (1e-4..1e15).contains(&x.abs()) {
        let t = x.to_string();
        if t.contains('.') {
            t
        } else {
            format!("{t}.0")
        }
    } else {
        format!("{x:e}")
    }
}

/// The matrix `rows` as a TOML array of arrays, one row per line.
pub fn matrix(name: &str, rows: impl Iterator<Item = Vec<f64>>) -> String {
    let mut out = format!("{name} = [\n");
    for row in rows {
        let cells: Vec<String> = row.into_iter().map(num).collect();
        let _ = writeln!(out, "  [{}],", cells.join(", "));
    }
    out.push_str("]\n");
    out
}

/// A state-space controller's matrices as written in files.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SsTable {
    a: Vec<Vec<f64>>,
    b: Vec<Vec<f64>>,
    c: Vec<Vec<f64>>,
    d: Vec<Vec<f64>>,
}

impl SsTable {
    /// The matrices, checked for shape and finiteness (keys under `prefix`: `controller.ss.`
    /// or the top level of a state-space file).
    fn matrices(&self, at: &Origin, prefix: &str) -> Result<SsMatrices, ConfigError> {
        let n = self.a.len();
        let shape = |key: &str, rows: &Vec<Vec<f64>>, r: usize, c: usize| {
            let ok = rows.len() == r
                && rows
                    .iter()
                    .all(|row| row.len() == c && row.iter().all(|x| x.is_finite()));
            if ok {
                Ok(())
            } else {
                let got = format!("{}×{}", rows.len(), rows.first().map_or(0, |x| x.len()));
                Err(at.invalid(
                    &format!("{prefix}{key}"),
                    got,
                    &format!(
                        "{r}×{c} finite numbers (controller order {n}, one input, one output)"
                    ),
                ))
            }
        };
        if n == 0 || n > MAX_SS_ORDER {
            return Err(at.invalid(
                &format!("{prefix}a"),
                format!("{n} states"),
                &format!("1..={MAX_SS_ORDER} states"),
            ));
        }
        shape("a", &self.a, n, n)?;
        shape("b", &self.b, n, 1)?;
        shape("c", &self.c, 1, n)?;
        shape("d", &self.d, 1, 1)?;
        Ok(SsMatrices::from_fn(n, |i, j| match (i < n, j < n) {
            (true, true) => self.a[i][j],
            (true, false) => self.b[i][0],
            (false, true) => self.c[0][j],
            (false, false) => self.d[0][0],
        })
        .expect("the order was checked"))
    }
}

/// `[controller]` as a deployment, a tuning fragment or a loaded file writes it.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct ControllerTable {
    kind: ControllerKind,
    pid: PidGains,
    ka: f64,
    kg_scaling: bool,
    accel_filter_hz: f64,
    accel_filter_order: u8,
    limit_v: f64,
    ss: Option<SsTable>,
    made_for: Option<MadeFor>,
    stability: Option<Stability>,
}

impl Default for ControllerTable {
    fn default() -> Self {
        let d = ControllerSpec::default();
        ControllerTable {
            kind: d.kind,
            pid: d.pid,
            ka: d.ka,
            kg_scaling: d.kg_scaling,
            accel_filter_hz: d.accel_filter_hz,
            accel_filter_order: d.accel_filter_order,
            limit_v: d.limit_v,
            ss: None,
            made_for: None,
            stability: None,
        }
    }
}

impl ControllerTable {
    fn spec(&self, at: &Origin) -> Result<ControllerSpec, ConfigError> {
        let ss = match (&self.ss, self.kind) {
            (Some(t), _) => Some(t.matrices(at, "controller.ss.")?),
            (None, ControllerKind::Ss) => {
                return Err(at.invalid(
                    "controller.ss",
                    "(missing)",
                    "the matrices a, b, c, d of a state-space controller for kind = \"ss\"",
                ))
            }
            (None, _) => None,
        };
        Ok(ControllerSpec {
            kind: self.kind,
            pid: self.pid,
            ka: self.ka,
            kg_scaling: self.kg_scaling,
            accel_filter_hz: self.accel_filter_hz,
            accel_filter_order: self.accel_filter_order,
            ss,
            limit_v: self.limit_v,
        })
    }
}

/// `[feedforward]` of a deployment.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
enum FeedforwardTable {
    #[default]
    None,
    Model,
    Zpetc {
        gain: f64,
        preview_ticks: usize,
        #[serde(deserialize_with = "super::exact::exact_arrays")]
        sections: Vec<[f64; 5]>,
    },
    Fir {
        preview_ticks: usize,
        stride_ticks: usize,
        taps: Vec<f64>,
    },
}

/// A deployment file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct DeploymentFile {
    servo_rate_hz: f64,
    #[serde(default)]
    smoothing_hz: f64,
    stage: Stage,
    controller: ControllerTable,
    #[serde(default)]
    reference: ReferenceSpec,
    #[serde(default)]
    feedforward: FeedforwardTable,
    #[serde(default)]
    protection: ProtectionConfig,
}

/// A deployment and what it was made for.
#[derive(Debug, Clone, PartialEq)]
pub struct DeploymentAndProvenance {
    /// The loop.
    pub deployment: Deployment,
    /// The plant and rate it was made for (`[controller.made_for]`).
    pub made_for: Option<MadeFor>,
}

fn parse_error(at: &Origin, text: &str, e: toml::de::Error) -> ConfigError {
    ConfigError::Parse {
        path: at.path.clone().unwrap_or_else(|| "(text)".into()),
        message: super::origin::toml_message(text, &e),
    }
}

/// Parses the deployment `text` (from `at`), checking every value ([`Deployment::check`]).
pub fn parse_deployment(text: &str, at: &Origin) -> Result<DeploymentAndProvenance, ConfigError> {
    let f: DeploymentFile = toml::from_str(text).map_err(|e| parse_error(at, text, e))?;
    let feedforward = match f.feedforward {
        FeedforwardTable::None => FeedforwardSpec::None,
        FeedforwardTable::Model => FeedforwardSpec::Model,
        FeedforwardTable::Zpetc {
            gain,
            preview_ticks,
            sections,
        } => {
            if sections.len() > ZPETC_SECTIONS {
                return Err(at.invalid(
                    "feedforward.sections",
                    format!("{} sections", sections.len()),
                    &format!("at most {ZPETC_SECTIONS}"),
                ));
            }
            let mut all = [[1.0, 0.0, 0.0, 0.0, 0.0]; ZPETC_SECTIONS];
            all[..sections.len()].copy_from_slice(&sections);
            FeedforwardSpec::Zpetc(ZpetcSpec {
                gain,
                preview: preview_ticks,
                sections: all,
                sections_used: sections.len(),
            })
        }
        FeedforwardTable::Fir {
            preview_ticks,
            stride_ticks,
            taps,
        } => {
            if taps.is_empty() || taps.len() > MAX_FIR_TAPS {
                return Err(at.invalid(
                    "feedforward.taps",
                    format!("{} taps", taps.len()),
                    &format!("1 to {MAX_FIR_TAPS}"),
                ));
            }
            let mut all = [0.0; MAX_FIR_TAPS];
            all[..taps.len()].copy_from_slice(&taps);
            FeedforwardSpec::Fir(FirSpec {
                taps: all,
                taps_used: taps.len(),
                preview: preview_ticks,
                stride: stride_ticks,
            })
        }
    };
    let deployment = Deployment {
        servo_rate_hz: f.servo_rate_hz,
        stage: f.stage,
        controller: f.controller.spec(at)?,
        stability: f.controller.stability,
        reference: f.reference,
        feedforward,
        smoothing_hz: f.smoothing_hz,
        protection: f.protection,
    };
    deployment.check().map_err(|e| at.located(&e))?;
    if let Some(m) = &f.controller.made_for {
        // What it says it was made for, checked at open as at a load: the rate it runs at.
        let rate = deployment.servo_rate_hz;
        if (m.servo_rate_hz - rate).abs() > 1e-6 * rate || m.servo_rate_hz.is_nan() {
            return Err(at.invalid(
                "controller.made_for.servo_rate_hz",
                m.servo_rate_hz,
                &format!("{rate} Hz: the loop's servo_rate_hz (a controller runs only at the rate it was made for)"),
            ));
        }
    }
    Ok(DeploymentAndProvenance {
        deployment,
        made_for: f.controller.made_for,
    })
}

/// The `[controller]` table of `c` (with its provenance and offline check) as TOML.
pub fn controller_toml(
    c: &ControllerSpec,
    made_for: Option<&MadeFor>,
    stability: Option<&Stability>,
) -> String {
    #[derive(Serialize)]
    struct Scalars {
        kind: ControllerKind,
        ka: f64,
        kg_scaling: bool,
        accel_filter_hz: f64,
        accel_filter_order: u8,
        limit_v: f64,
    }
    let mut out = String::from("[controller]\n");
    out += &toml::to_string(&Scalars {
        kind: c.kind,
        ka: c.ka,
        kg_scaling: c.kg_scaling,
        accel_filter_hz: c.accel_filter_hz,
        accel_filter_order: c.accel_filter_order,
        limit_v: c.limit_v,
    })
    .expect("scalars serialise");
    let p = &c.pid;
    let _ = write!(
        out,
        "\n[controller.pid]\nkp = {}\nki = {}\nkd = {}\ntf_s = {}\n",
        num(p.kp),
        num(p.ki),
        num(p.kd),
        num(p.tf_s)
    );
    if let Some(m) = &c.ss {
        let n = m.order();
        out += "\n[controller.ss]\n";
        out += &matrix("a", (0..n).map(|i| (0..n).map(|j| m.entry(i, j)).collect()));
        out += &matrix("b", (0..n).map(|i| vec![m.entry(i, n)]));
        out += &matrix(
            "c",
            std::iter::once((0..n).map(|j| m.entry(n, j)).collect()),
        );
        out += &matrix("d", std::iter::once(vec![m.entry(n, n)]));
    }
    if let Some(m) = made_for {
        out += "\n";
        out += &m.to_toml("controller.made_for");
    }
    if let Some(s) = stability {
        out += "\n";
        out += &stability_toml("controller.stability", s);
    }
    out
}

/// The stability record `s` as the TOML table `[table]`, with its seal as `[table.sha256]`.
pub fn stability_toml(table: &str, s: &Stability) -> String {
    let hex = |d: &[u8; 32]| d.iter().map(|b| format!("{b:02x}")).collect::<String>();
    format!(
        "[{table}]\nspectral_radius = {}\nunstable_below = {}\nunstable_above = {}\n\n[{table}.sha256]\nstage = \"{}\"\ncontroller = \"{}\"\nrecord = \"{}\"\n",
        num(s.spectral_radius),
        num(s.unstable_below),
        num(s.unstable_above),
        hex(&s.sha256.stage),
        hex(&s.sha256.controller),
        hex(&s.sha256.record)
    )
}

/// The deployment `d` (made for `made_for`) as TOML, opened by the comment `header`.
pub fn deployment_toml(d: &Deployment, made_for: Option<&MadeFor>, header: &str) -> String {
    let mut out = String::new();
    for line in header.lines() {
        let _ = writeln!(out, "# {line}");
    }
    let _ = writeln!(
        out,
        "servo_rate_hz = {}\nsmoothing_hz = {}\n",
        num(d.servo_rate_hz),
        num(d.smoothing_hz)
    );
    out += "[stage]\n";
    out += &toml::to_string(&d.stage).expect("the stage serialises");
    out += "\n";
    out += &controller_toml(&d.controller, made_for, d.stability.as_ref());
    #[derive(Serialize)]
    struct Reference<'a> {
        reference: &'a ReferenceSpec,
        protection: &'a ProtectionConfig,
    }
    out += "\n[feedforward]\n";
    match &d.feedforward {
        FeedforwardSpec::None => out += "kind = \"none\"\n",
        FeedforwardSpec::Model => out += "kind = \"model\"\n",
        FeedforwardSpec::Zpetc(z) => {
            let _ = write!(
                out,
                "kind = \"zpetc\"\ngain = {}\npreview_ticks = {}\n",
                num(z.gain),
                z.preview
            );
            out += &matrix(
                "sections",
                z.sections[..z.sections_used].iter().map(|s| s.to_vec()),
            );
        }
        FeedforwardSpec::Fir(f) => {
            let _ = writeln!(
                out,
                "kind = \"fir\"\npreview_ticks = {}\nstride_ticks = {}",
                f.preview, f.stride
            );
            let taps: Vec<String> = f.taps[..f.taps_used].iter().map(|&t| num(t)).collect();
            let _ = writeln!(out, "taps = [{}]", taps.join(", "));
        }
    }
    out += "\n";
    out += &toml::to_string(&Reference {
        reference: &d.reference,
        protection: &d.protection,
    })
    .expect("reference and protection serialise");
    out
}

/// A controller file loaded into a running loop: what it holds, and what it says it was made
/// for and checked against.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerFile {
    /// The controller.
    pub spec: ControllerSpec,
    /// The plant and rate it was made for, if it says.
    pub made_for: Option<MadeFor>,
    /// The offline check of its loop, if it carries one.
    pub stability: Option<Stability>,
    /// The sample rate a state-space file says it was designed for, Hz (checked against the
    /// loop's by the caller, after what it was made for).
    pub sample_rate_hz: Option<f64>,
}

/// A state-space controller file as `servo synth` (MATLAB, python-control) writes it.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SsFile {
    sample_rate_hz: f64,
    a: Vec<Vec<f64>>,
    b: Vec<Vec<f64>>,
    c: Vec<Vec<f64>>,
    d: Vec<Vec<f64>>,
    made_for: Option<MadeFor>,
    stability: Option<Stability>,
}

/// A `[controller]` fragment (a tuning fragment may carry the `[plant]` it was made for: that
/// plant is what its `[controller.made_for]` hashes, and is not read here).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct Fragment {
    controller: ControllerTable,
    #[allow(dead_code)] // accepted, not read: see the type's documentation
    plant: Option<toml::Table>,
}

/// Parses a controller file for a loop whose other settings are `running` (a state-space file
/// takes the running loop's output limit): a state-space file (`sample_rate_hz`, `a`, `b`,
/// `c`, `d`, `[made_for]`, `[stability]`) or a `[controller]` fragment.
pub fn parse_controller_file(
    text: &str,
    at: &Origin,
    running: &ControllerSpec,
) -> Result<ControllerFile, ConfigError> {
    // Parsed twice: once to see which form it is, then from the text again, so that an error
    // points at its own line (a table converted afterwards has no positions left).
    let table: toml::Table = toml::from_str(text).map_err(|e| parse_error(at, text, e))?;
    if table.contains_key("controller") {
        let f: Fragment = toml::from_str(text).map_err(|e| parse_error(at, text, e))?;
        return Ok(ControllerFile {
            spec: f.controller.spec(at)?,
            made_for: f.controller.made_for,
            stability: f.controller.stability,
            sample_rate_hz: None,
        });
    }
    let f: SsFile = toml::from_str(text).map_err(|e| parse_error(at, text, e))?;
    let m = SsTable {
        a: f.a,
        b: f.b,
        c: f.c,
        d: f.d,
    }
    .matrices(at, "")?;
    Ok(ControllerFile {
        spec: ControllerSpec {
            kind: ControllerKind::Ss,
            ss: Some(m),
            ..running.clone()
        },
        made_for: f.made_for,
        stability: f.stability,
        sample_rate_hz: Some(f.sample_rate_hz),
    })
}

impl ControllerFile {
    /// Checks that a state-space file was designed for `servo_rate_hz` (Hz); `running_key`
    /// names the loop's rate where the caller configures it.
    pub fn check_rate(
        &self,
        servo_rate_hz: f64,
        at: &Origin,
        running_key: &str,
    ) -> Result<(), ConfigError> {
        let Some(rate) = self.sample_rate_hz else {
            return Ok(());
        };
        let off = (rate - servo_rate_hz).abs();
        if off.is_nan() || off > 1e-6 * servo_rate_hz {
            return Err(at.invalid(
                "sample_rate_hz",
                rate,
                &format!("{servo_rate_hz} Hz ({running_key})"),
            ));
        }
        Ok(())
    }
}
